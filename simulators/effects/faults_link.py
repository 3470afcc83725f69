"""Link faults: a garbled byte, a reply that never comes, a device unplugged mid-shot.

"Shot n" for a reply means a command handled after shot n-1's FIRE and up to shot n's FIRE; for
an event it means an event that shot n caused. A listed shot strikes the first matching message.
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Literal

from pydantic import Field

from rig.simulators.effects.base import Effect, FaultConfig, Strikes
from rig.simulators.records import Outgoing

if TYPE_CHECKING:
    from rig.simulators.scene import Scene

Device = Literal["cannon", "gates", "clamp"]


def garble(data: bytes) -> bytes:
    """Flip the low bit of the middle byte of the body: the CRC no longer matches."""
    star = data.rfind(b"*")
    if star <= 0:
        return data
    i = star // 2
    # 0x01 keeps the byte off '\n' and '\r', so the frame's length stays the same.
    return data[:i] + bytes([data[i] ^ 0x01]) + data[i + 1 :]


def _matches(message: Outgoing, device: str, kind: str, name: str | None) -> bool:
    return message.device == device and message.kind == kind and name in (None, message.name)


class GarbledConfig(FaultConfig):
    """Which device's messages get a corrupted byte."""

    kind: Literal["garbled"] = "garbled"
    device: Device = "gates"
    message: Literal["reply", "event"] = "event"
    name: str | None = Field(None, max_length=32, description="command verb (reply) or event name; none: any")

    def build(self, scene: Scene, rng: random.Random) -> Garbled:
        """A Garbled."""
        return Garbled(self, scene, rng)


class Garbled(Effect):
    """Corrupts one byte of a matching message."""

    config: GarbledConfig

    def __init__(self, config: GarbledConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def outgoing(self, message: Outgoing) -> bytes | None:
        """The message, garbled if the fault strikes."""
        c = self.config
        if _matches(message, c.device, c.message, c.name) and self.strikes.now(message.shot):
            return garble(message.data)
        return message.data


class DroppedReplyConfig(FaultConfig):
    """Which device's replies may be lost."""

    kind: Literal["dropped_reply"] = "dropped_reply"
    device: Device = "cannon"
    name: str | None = Field(
        None, max_length=32, description="command verb whose reply is dropped; none: any"
    )

    def build(self, scene: Scene, rng: random.Random) -> DroppedReply:
        """A DroppedReply."""
        return DroppedReply(self, scene, rng)


class DroppedReply(Effect):
    """Swallows a matching reply (the command still takes effect)."""

    config: DroppedReplyConfig

    def __init__(self, config: DroppedReplyConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def outgoing(self, message: Outgoing) -> bytes | None:
        """None if the fault strikes."""
        c = self.config
        if _matches(message, c.device, "reply", c.name) and self.strikes.now(message.shot):
            return None
        return message.data


class UnplugConfig(FaultConfig):
    """Which device drops off the bus during a shot, and after how many of the shot's messages."""

    kind: Literal["unplug"] = "unplug"
    device: Device = "gates"
    after: int = Field(1, ge=0, le=100, description="messages of the shot delivered before the unplug")

    def build(self, scene: Scene, rng: random.Random) -> Unplug:
        """An Unplug."""
        return Unplug(self, scene, rng)


class Unplug(Effect):
    """Unplugs the device mid-shot; it stays unplugged until the port is opened again."""

    config: UnplugConfig

    def __init__(self, config: UnplugConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def unplug_after(self, device: str, shot: int) -> int | None:
        """The message count after which the device vanishes, on a struck shot."""
        if device == self.config.device and self.strikes.now(shot):
            return self.config.after
        return None
