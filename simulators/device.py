"""The device side of a wire codec, common to the three simulated devices.

A SimDevice takes the host's bytes with `write`, decodes them with the device's DeviceCodec and
answers every well-formed command exactly once; it hands its output to the host with `read` and
`in_waiting`. A BadCommand gets an ERR reply; a garbled line gets no answer (its sequence number
cannot be trusted). All state lives in, and all calls lock, the SimWorld the device belongs to.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, ClassVar

from rig.drivers.codec import BadCommand, CheckedCommand, CommandSpec, DeviceCodec
from rig.drivers.wire import Garbled
from rig.simulators.records import Outgoing
from rig.simulators.timeline import OutputQueue

if TYPE_CHECKING:
    from rig.simulators.world import SimWorld


class Unplugged(ConnectionError):
    """The simulated device was unplugged (a fault); it stays so until `replug()`."""


class SimDevice:
    """Base of SimCannon, SimGates and SimClamp."""

    name: ClassVar[str]
    specs: ClassVar[Mapping[str, CommandSpec]]
    identity: ClassVar[dict[str, str]]

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        self.codec = DeviceCodec(self.specs)
        self.out = OutputQueue()
        self.unplugged = False
        self._shot = 1  # the shot the command being handled belongs to

    # -- host side -------------------------------------------------------------------------
    def write(self, data: bytes) -> int:
        """Bytes from the host: handle every complete command they finish."""
        with self.world.lock:
            if self.unplugged:
                raise Unplugged(f"{self.name} unplugged")
            for item in self.codec.feed(bytes(data)):
                if isinstance(item, Garbled):
                    continue
                self._shot = self.world.attempts + 1
                if isinstance(item, BadCommand):
                    self._send("reply", item.seq, "?", self.codec.error(item.seq, item.code, item.text))
                else:
                    self.handle(item)
            self.world.changed.notify_all()
        return len(data)

    def read(self, size: int = -1) -> bytes:
        """Up to `size` bytes for the host (all if negative); advances the world's clock to them."""
        with self.world.lock:
            data, latest = self.out.take(size)
            if not data and self.out.at_unplug():
                self.unplugged = True
                raise Unplugged(f"{self.name} unplugged")
            if latest is not None:
                self.world.advance_to(latest)
            return data

    @property
    def in_waiting(self) -> int:
        """Bytes the host can read now."""
        with self.world.lock:
            if self.out.at_unplug():
                self.unplugged = True
                raise Unplugged(f"{self.name} unplugged")
            return self.out.pending()

    def replug(self) -> None:
        """Plug the device back in: buffers and the half-received line are lost, state is kept."""
        with self.world.lock:
            self.world.cancel(f"unplug-{self.name}")
            self.unplugged = False
            self.out.clear()
            self.codec = DeviceCodec(self.specs)

    # -- for the subclasses -----------------------------------------------------------------
    def handle(self, cmd: CheckedCommand) -> None:
        """Act on one well-formed command; answer it with `ok` or `refuse`."""
        if cmd.verb == "ID":
            self.ok(cmd, self.identity)
        else:  # pragma: no cover - every SPECS verb is handled by the subclass
            self.refuse(cmd, "UNKNOWN", f"no command {cmd.verb}")

    def ok(self, cmd: CheckedCommand, values: Mapping[str, object] | None = None) -> None:
        """Answer `cmd` positively."""
        self._send("reply", cmd.seq, cmd.verb, self.codec.ok(cmd.seq, values))

    def refuse(self, cmd: CheckedCommand, code: str, text: str = "") -> None:
        """Answer `cmd` with an error code."""
        self._send("reply", cmd.seq, cmd.verb, self.codec.error(cmd.seq, code, text))

    def emit(
        self,
        name: str,
        values: Mapping[str, object] | None = None,
        at: float | None = None,
        tag: str | None = None,
        shot: int = 0,
    ) -> None:
        """Queue an event for virtual time `at` (default now); `shot` marks it caused by that shot."""
        time_s = self.world.clock if at is None else at
        data = self.codec.event(name, values)
        hooks = self.world.hooks["outgoing"]
        if hooks:
            sent = self.world.filter_outgoing(Outgoing(self.name, "event", name, shot or self._shot, data))
            if sent is None:
                return
            data = sent
        self.out.push(time_s, data, tag, shot)

    def _send(self, kind: str, seq: int, verb: str, data: bytes) -> None:
        hooks = self.world.hooks["outgoing"]
        if hooks:
            spoiled = self.world.filter_outgoing(Outgoing(self.name, kind, verb, self._shot, data))
            if spoiled is None:
                return
            data = spoiled
        self.out.push(self.world.clock, data)
