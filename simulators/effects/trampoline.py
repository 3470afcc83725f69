"""Trampoline barrel: the hoop mode of a hollow barrel returns energy to the ball.

Without this effect the barrel is rigid. With it, the apparent COR at a distance q from the pivot
blends the rigid barrel and the flexible barrel of rig.physics (hoop frequency of the scene's bat):

    e_A(q) = e_rigid(q) + w(q) (e_hoop(q) + d(q) - e_rigid(q)),   w(q) = exp(-((q - q_s) / width)^2 / 2)

q_s is the sweet spot, `sweet_spot_from_tip_m` in from the barrel's tip. The weight stands for
how much of the hoop mode the ball excites: the mode's antinode sits near the sweet zone (Russell,
Acoustics Today 2017) and the barrel stiffens towards the taper and the end cap. The Gaussian shape
and its width are assumptions, chosen so that a location scan shows one maximum near the sweet spot.

The barrel's "true" constants are the scene's own (`m2`, `c2`, `k1_scale`; unset: the ball
model's, i.e. the founding paper's), so a simulated population needs calibrating as a real one
does. d(q) is the bat's own performance beyond the model: a bat-to-bat offset drawn once per bat
(normal, standard deviation `spread_bbcor`, from the scene seed and the bat's id) plus the
`alteration_bbcor` of an altered bat, both in BBCOR units and turned into e_A at the impact point
(BBCOR = e_A (1 + k) + k, rig.measure.metrics), so that at the sweet spot they raise the BBCOR
by exactly that much.

Off the sweet spot a real bat also loses energy to its bending vibration (the sweet spot sits near
the first bending mode's node). `off_node_loss_bbcor` = L takes L (1 - w(q)) BBCOR off the
result (0 at the sweet spot, L far from it), so that a location scan peaks near the sweet spot
rather than riding the rigid barrel's slow rise towards the handle. The shape is an assumption.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import Field

from rig.measure.metrics import recoil_factor
from rig.physics import CollisionParams
from rig.simulators.effects.base import Effect, EffectConfig
from rig.simulators.physics import SolveCache, solve_pivoted

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class TrampolineConfig(EffectConfig):
    """Where the sweet spot is, how fast the trampoline falls off, and the barrel's true constants."""

    kind: Literal["trampoline"] = "trampoline"
    slot: ClassVar[str | None] = "collision"
    sweet_spot_from_tip_m: float = Field(0.165, gt=0.0, le=0.5, description="m in from the tip (6.5 in)")
    width_m: float = Field(0.08, gt=0.0, le=1.0, description="one-sigma width of the weight w(q), m")
    m2: float | None = Field(
        None, gt=0.0, le=1.0, description="true effective hoop mass, kg (unset: the ball model's m2)"
    )
    c2: float | None = Field(
        None, ge=0.0, le=1e5, description="true hoop damping, N s/m (unset: the ball model's c2)"
    )
    k1_scale: float = Field(1.0, ge=0.1, le=10.0, description="true factor on the ball's contact stiffness")
    spread_bbcor: float = Field(
        0.0, ge=0.0, le=0.05, description="bat-to-bat standard deviation of the performance, BBCOR"
    )
    off_node_loss_bbcor: float = Field(
        0.0, ge=0.0, le=0.3, description="BBCOR lost to bending vibration far from the sweet spot"
    )
    alteration_bbcor: float = Field(
        0.0, ge=-0.2, le=0.2, description="extra performance of an altered bat, BBCOR (0: legal)"
    )

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A Trampoline."""
        return Trampoline(self, scene, rng)


def bat_offset_bbcor(seed: int, bat_id: str, spread_bbcor: float) -> float:
    """The bat's own performance offset, BBCOR: the same for this bat in every session and process."""
    if spread_bbcor == 0.0:
        return 0.0
    # A str seed is hashed with SHA-512 by random.Random: independent of PYTHONHASHSEED.
    return random.Random(f"{seed}/bat-offset/{bat_id}").gauss(0.0, spread_bbcor)


class Trampoline(Effect):
    """Fills the `collision` slot."""

    config: TrampolineConfig

    def __init__(self, config: TrampolineConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.moi = scene.bat.moi_kgm2
        self.hoop_hz = scene.bat.hoop_hz
        self.sweet_spot_m = scene.bat.length_m - config.sweet_spot_from_tip_m - scene.rig.pivot_from_knob_m
        self.offset_bbcor = bat_offset_bbcor(scene.seed, scene.bat.id, config.spread_bbcor)
        self.extra_bbcor = self.offset_bbcor + config.alteration_bbcor
        self._cache = SolveCache()

    def set_hoop_hz(self, hoop_hz: float) -> None:
        """The barrel's hoop frequency changed (rolled in: rig.simulators.effects.softening)."""
        self.hoop_hz = hoop_hz
        self._cache = SolveCache()

    def barrel(self, params: CollisionParams) -> CollisionParams:
        """The ball's constants (as this shot's ball has them) with the scene's true barrel."""
        c = self.config
        if c.m2 is None and c.c2 is None and c.k1_scale == 1.0:
            return params
        return params.model_copy(
            update={
                "m2": params.m2 if c.m2 is None else c.m2,
                "c2": params.c2 if c.c2 is None else c.c2,
                "k1": params.k1 * c.k1_scale,
            }
        )

    def weight(self, q: float) -> float:
        """Share of the hoop mode's effect at q m from the pivot (1 at the sweet spot)."""
        return math.exp(-0.5 * ((q - self.sweet_spot_m) / self.config.width_m) ** 2)

    def extra_e_a(self, params: CollisionParams, q: float) -> float:
        """The bat's offset and alteration as e_A at q (d BBCOR = (1 + k) d e_A)."""
        if self.extra_bbcor == 0.0:
            return 0.0
        return self.extra_bbcor / (1.0 + recoil_factor(q, self.moi, params.m1))

    def collide(self, params: CollisionParams, speed: float, q: float) -> tuple[float, float]:
        """(e_A, contact time) blended between the rigid and the flexible barrel."""
        key = (params, speed, q)
        hit = self._cache.get(key)
        if hit is None:
            true = self.barrel(params)
            e_r, tc_r = solve_pivoted(true, speed, None, self.moi, q)
            e_h, tc_h = solve_pivoted(true, speed, self.hoop_hz, self.moi, q)
            e_h += self.extra_e_a(params, q)
            w = self.weight(q)
            loss = self.config.off_node_loss_bbcor * (1.0 - w) / (1.0 + recoil_factor(q, self.moi, params.m1))
            hit = (e_r + w * (e_h - e_r) - loss, tc_r + w * (tc_h - tc_r))
            self._cache.put(key, hit)
        return hit
