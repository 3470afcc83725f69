"""Cannon faults: a misfire, and an interlock that opens while the cannon is armed."""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Literal

from pydantic import Field

from rig.simulators.effects.base import Effect, FaultConfig, Strikes

if TYPE_CHECKING:
    from rig.simulators.scene import Scene
    from rig.simulators.world import SimWorld


class MisfireConfig(FaultConfig):
    """FIRE is accepted but no ball leaves: `! FAULT CODE=MISFIRE`, tank vented, RESET needed."""

    kind: Literal["misfire"] = "misfire"

    def build(self, scene: Scene, rng: random.Random) -> Misfire:
        """A Misfire."""
        return Misfire(self, scene, rng)


class Misfire(Effect):
    """Decides whether a FIRE misfires."""

    def __init__(self, config: MisfireConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def misfire(self, shot: int) -> bool:
        """True on a struck shot."""
        return self.strikes.now(shot)


class InterlockConfig(FaultConfig):
    """Which interlock opens just after ARM, and when it closes again (virtual seconds)."""

    kind: Literal["interlock"] = "interlock"
    interlock: Literal["door", "estop"] = "door"
    reclose_after_s: float = Field(2.0, gt=0.0, le=3600.0)

    def build(self, scene: Scene, rng: random.Random) -> InterlockOpens:
        """An InterlockOpens."""
        return InterlockOpens(self, scene, rng)


class InterlockOpens(Effect):
    """Opens the interlock right after ARM (the cannon vents to SAFE), closes it later."""

    config: InterlockConfig

    def __init__(self, config: InterlockConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.strikes = Strikes(config, rng)

    def after_arm(self, world: SimWorld, shot: int) -> None:
        """Open the interlock now and schedule it to close."""
        if self.strikes.now(shot):
            name = self.config.interlock
            world.set_interlock(name, False)
            world.set_interlock(name, True, at=world.clock + self.config.reclose_after_s)
