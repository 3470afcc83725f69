"""Air drag between the muzzle, the gates and the bat: quadratic drag in closed form.

With m dv/dt = -1/2 rho Cd A v^2 and no other force, the speed falls as v(x) = v0 exp(-x/L) and
the time to cover x is t(x) = (L/v0)(exp(x/L) - 1), where L = 2 m / (rho Cd A) is the drag length
(about 160 m for a baseball). Gravity and spin are left out of the flight along the line.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import Field

from simulators.effects.base import Effect, EffectConfig

if TYPE_CHECKING:
    from simulators.scene import Scene


class DragConfig(EffectConfig):
    """Drag coefficient, air density and ball diameter (the ball's mass is the scene's m1)."""

    kind: Literal["drag"] = "drag"
    slot: ClassVar[str | None] = "flight"
    drag_coefficient: float = Field(0.35, gt=0.0, le=2.0, description="Cd, dimensionless")
    air_density: float = Field(1.20, gt=0.0, le=2.0, description="kg/m^3")
    ball_diameter_m: float = Field(0.0737, gt=0.0, le=0.2, description="m (2.9 in)")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A Drag."""
        return Drag(self, scene, rng)


class Drag(Effect):
    """Fills the `flight` slot."""

    config: DragConfig

    def __init__(self, config: DragConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        area = math.pi * (config.ball_diameter_m / 2.0) ** 2
        self.length_m = 2.0 * scene.ball.m1 / (config.air_density * config.drag_coefficient * area)

    def time_to(self, distance: float, speed: float) -> float:
        """(L/v0) (exp(x/L) - 1), with expm1 so short distances keep full precision."""
        return self.length_m / speed * math.expm1(distance / self.length_m)

    def speed_at(self, distance: float, speed: float) -> float:
        """v0 exp(-x/L)."""
        return speed * math.exp(-distance / self.length_m)
