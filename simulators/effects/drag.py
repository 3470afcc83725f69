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

from rig.simulators.effects.base import Effect, EffectConfig

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class DragConfig(EffectConfig):
    """Drag coefficient, air density and ball diameter (the ball's mass is the scene's m1)."""

    kind: Literal["drag"] = "drag"
    slot: ClassVar[str | None] = "flight"
    # Physical bounds: a sphere's Cd stays above ~0.07 past the drag crisis and below ~1.5; air from
    # a high-altitude lab (~0.7 kg/m^3) to cold sea-level air (~1.4); a ball from 2 in to a softball.
    drag_coefficient: float = Field(0.35, ge=0.05, le=1.5, description="Cd, dimensionless, 0.05-1.5")
    air_density: float = Field(1.20, ge=0.5, le=1.5, description="kg/m^3, 0.5-1.5")
    ball_diameter_m: float = Field(0.0737, ge=0.05, le=0.12, description="m (2.9 in), 0.05-0.12")

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
