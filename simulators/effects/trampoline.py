"""Trampoline barrel: the hoop mode of a hollow barrel returns energy to the ball.

Without this effect the barrel is rigid. With it, the apparent COR at a distance q from the pivot
blends the rigid barrel and the flexible barrel of rig.physics (hoop frequency of the scene's bat):

    e_A(q) = e_rigid(q) + w(q) (e_hoop(q) - e_rigid(q)),   w(q) = exp(-((q - q_s) / width)^2 / 2)

q_s is the sweet spot, `sweet_spot_from_tip_m` in from the barrel's tip. The weight stands for
how much of the hoop mode the ball excites: the mode's antinode sits near the sweet zone (Russell,
Acoustics Today 2017) and the barrel stiffens towards the taper and the end cap. The Gaussian shape
and its width are assumptions, chosen so that a location scan shows one maximum near the sweet spot.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import Field

from rig.physics import CollisionParams
from simulators.effects.base import Effect, EffectConfig
from simulators.physics import SolveCache, solve_pivoted

if TYPE_CHECKING:
    from simulators.scene import Scene


class TrampolineConfig(EffectConfig):
    """Where the sweet spot is and how fast the trampoline falls off away from it."""

    kind: Literal["trampoline"] = "trampoline"
    slot: ClassVar[str | None] = "collision"
    sweet_spot_from_tip_m: float = Field(0.165, gt=0.0, le=0.5, description="m in from the tip (6.5 in)")
    width_m: float = Field(0.08, gt=0.0, le=1.0, description="one-sigma width of the weight w(q), m")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A Trampoline."""
        return Trampoline(self, scene, rng)


class Trampoline(Effect):
    """Fills the `collision` slot."""

    config: TrampolineConfig

    def __init__(self, config: TrampolineConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.moi = scene.bat.moi_kgm2
        self.hoop_hz = scene.bat.hoop_hz
        self.sweet_spot_m = scene.bat.length_m - config.sweet_spot_from_tip_m - scene.rig.pivot_from_knob_m
        self._cache = SolveCache()

    def weight(self, q: float) -> float:
        """Share of the hoop mode's effect at q m from the pivot (1 at the sweet spot)."""
        return math.exp(-0.5 * ((q - self.sweet_spot_m) / self.config.width_m) ** 2)

    def collide(self, params: CollisionParams, speed: float, q: float) -> tuple[float, float]:
        """(e_A, contact time) blended between the rigid and the flexible barrel."""
        key = (params, speed, q)
        hit = self._cache.get(key)
        if hit is None:
            e_r, tc_r = solve_pivoted(params, speed, None, self.moi, q)
            e_h, tc_h = solve_pivoted(params, speed, self.hoop_hz, self.moi, q)
            w = self.weight(q)
            hit = (e_r + w * (e_h - e_r), tc_r + w * (tc_h - tc_r))
            self._cache.put(key, hit)
        return hit
