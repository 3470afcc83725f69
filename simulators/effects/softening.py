"""Barrel softening: a composite barrel rolled in (accelerated break-in) loses stiffness for good.

The barrel's wall stiffness is a fraction s of the new barrel's (s = 1 new). Rolling n passes at a
depth d (the rollers' squeeze, inches) breaks the matrix in a little more:

    s' = s_floor + (s - s_floor) exp(-rate n (d / d_ref)^p)

so that passes add (n passes at once = n single passes), deeper rolling hurts faster, and the
barrel never softens past its fibres' own stiffness (s_floor). The founding paper's barrel is a
hoop mode m2 on a spring k2 = m2 (2 pi f)^2: the wall's stiffness is k2, so the hoop frequency
falls as f = f0 sqrt(s) and the trampoline (this scene's collision, rig.simulators.effects.trampoline)
rises with it; the static squeeze of the compression tester (force at a fixed displacement) falls
as s itself: F = K0 s delta. The rolling law's shape and every constant below are assumptions [U]:
no published rolling-stiffness curve was found (lab-practice.md, "Accelerated break-in").

The effect is state, not a hook: the world (SimWorld.roll) rolls it when the simulated operator
rolls the bat, and tells the collision the new hoop frequency.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, Literal

from pydantic import Field

from rig.simulators.effects.base import Effect, EffectConfig

if TYPE_CHECKING:
    from rig.simulators.scene import Scene

REFERENCE_DEPTH_IN = 0.0125  # the NCAA ABI's rolling step, about 0.0125 in [C, lab-practice.md]


class BarrelSofteningConfig(EffectConfig):
    """The new barrel's diametral stiffness and how rolling lowers it (all [assumed])."""

    kind: Literal["barrel_softening"] = "barrel_softening"
    stiffness_lbf_per_in: float = Field(
        6000.0, gt=0.0, le=1e5, description="new barrel's diametral stiffness at 6 in, lbf/in [assumed]"
    )
    floor: float = Field(0.55, gt=0.0, lt=1.0, description="stiffness fraction left when fully broken in")
    rate: float = Field(0.01, ge=0.0, le=1.0, description="stiffness lost per pass at the reference depth")
    depth_exponent: float = Field(2.0, ge=0.0, le=4.0, description="p: deeper rolling hurts as (d/d_ref)^p")
    damage_below: float = Field(
        0.70, gt=0.0, le=1.0, description="stiffness fraction below which the barrel shows cracks"
    )
    noise_lbf: float = Field(0.5, ge=0.0, le=50.0, description="load cell's noise (SD) per reading, lbf")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A BarrelSoftening."""
        return BarrelSoftening(self, scene, rng)


def stiffness_after(s: float, depth_in: float, passes: int, config: BarrelSofteningConfig) -> float:
    """The stiffness fraction after `passes` passes at `depth_in` from `s` (the law above)."""
    if depth_in < 0.0 or passes < 0:
        raise ValueError(f"rolling needs depth >= 0 and passes >= 0, not {depth_in!r} in, {passes!r}")
    dose = config.rate * passes * (depth_in / REFERENCE_DEPTH_IN) ** config.depth_exponent
    return config.floor + (s - config.floor) * math.exp(-dose)


class BarrelSoftening(Effect):
    """The barrel's current stiffness; rolled by the world, read by the compression tester."""

    config: BarrelSofteningConfig

    def __init__(self, config: BarrelSofteningConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.new_hoop_hz = scene.bat.hoop_hz
        self.stiffness = 1.0
        self.rolled: list[tuple[float, int]] = []  # (depth in, passes) of every rolling, in order

    def roll(self, depth_in: float, passes: int) -> None:
        """Roll the barrel: `passes` passes at `depth_in`."""
        self.stiffness = stiffness_after(self.stiffness, depth_in, passes, self.config)
        self.rolled.append((depth_in, passes))

    @property
    def hoop_hz(self) -> float:
        """The barrel's hoop frequency now: f0 sqrt(s)."""
        return self.new_hoop_hz * math.sqrt(self.stiffness)

    @property
    def damaged(self) -> bool:
        """Whether the barrel shows cracks (an inspection would find them)."""
        return self.stiffness < self.config.damage_below

    def true_force_lbf(self, displacement_in: float) -> float:
        """The force a perfect load cell reads at `displacement_in`: K0 s delta."""
        return self.config.stiffness_lbf_per_in * self.stiffness * displacement_in

    def read_force_lbf(self, displacement_in: float) -> float:
        """The load cell's reading: the true force with its noise."""
        return self.true_force_lbf(displacement_in) + self.rng.gauss(0.0, self.config.noise_lbf)
