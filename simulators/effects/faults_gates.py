"""Gate faults: a beam break the counter misses, and one it latches twice.

A missed trigger is a gate that fails to see the ball (dirty lens, the ball passing low); a double
trigger is a second break soon after the first (a seam or a torn cover re-breaking the beam).
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Literal

from pydantic import Field, StrictBool

from rig.simulators.effects.base import Effect, FaultConfig, Strikes
from rig.simulators.records import Crossing

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class MissedTriggerConfig(FaultConfig):
    """Which gate misses, and on which pass of the ball."""

    kind: Literal["missed_trigger"] = "missed_trigger"
    gate: int = Field(2, ge=1, le=16)
    inbound: StrictBool = Field(True, description="true: the inbound crossing is missed; false: the rebound")

    def build(self, scene: Scene, rng: random.Random) -> MissedTrigger:
        """A MissedTrigger."""
        return MissedTrigger(self, scene, rng)


class MissedTrigger(Effect):
    """Drops the gate's crossing on a struck shot."""

    config: MissedTriggerConfig

    def __init__(self, config: MissedTriggerConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def crossings(self, crossings: list[Crossing], shot: int) -> list[Crossing]:
        """The crossings without the missed one."""
        if not self.strikes.now(shot):
            return crossings
        c = self.config
        return [x for x in crossings if not (x.gate == c.gate and x.inbound == c.inbound)]


class DoubleTriggerConfig(FaultConfig):
    """Which gate triggers twice, on which pass, and how long after the true break."""

    kind: Literal["double_trigger"] = "double_trigger"
    gate: int = Field(1, ge=1, le=16)
    inbound: StrictBool = True
    delay_us: float = Field(40.0, gt=0.0, le=1e5, description="second break after the first, us")

    def build(self, scene: Scene, rng: random.Random) -> DoubleTrigger:
        """A DoubleTrigger."""
        return DoubleTrigger(self, scene, rng)


class DoubleTrigger(Effect):
    """Adds a second break of the gate on a struck shot."""

    config: DoubleTriggerConfig

    def __init__(self, config: DoubleTriggerConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def crossings(self, crossings: list[Crossing], shot: int) -> list[Crossing]:
        """The crossings plus the echo, in time order."""
        if not self.strikes.now(shot):
            return crossings
        c = self.config
        echoes = [
            Crossing(x.gate, x.time_s + c.delay_us * 1e-6, x.inbound)
            for x in crossings
            if x.gate == c.gate and x.inbound == c.inbound
        ]
        return sorted(crossings + echoes, key=lambda x: x.time_s)
