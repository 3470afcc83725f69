"""The simulated truth as a standard means it, computed from the scene without the measurement chain.

A certified value is compared with what the simulated bat really is: the metric at the scanned
location of maximum, at the standard's speed (60.8 m/s for BBCOR), with a new ball of the lot's
nominal condition (the scene's `ball`: no ball-to-ball offset, no wear, 21 C and 50 % RH) and the
bat's true MOI. No gate, drag, scatter, timing or environment effect enters: they are how the rig
measures, not what the bat is.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from rig.core.units import INCH
from rig.measure.metrics import compute_metrics
from rig.simulators.physics import Collision, RigidCollision
from rig.simulators.scene import Scene

BBCOR_SPEED_M_S = 60.8  # the NCAA BBCOR procedure's inbound speed (protocols/bbcor.toml)


@dataclass(frozen=True)
class Truth:
    """The true metric at each scanned location and its maximum."""

    metric: str
    speed_m_s: float
    by_location: dict[float, float]  # location from the barrel end (in) -> true metric

    @property
    def location_in(self) -> float:
        """The scanned location of maximum (the first of equal maxima)."""
        return max(self.by_location, key=lambda k: (self.by_location[k], -k))

    @property
    def value(self) -> float:
        """The true metric there."""
        return self.by_location[self.location_in]


def collision_of(scene: Scene) -> Collision:
    """The scene's collision: its `collision` slot effect (e.g. the trampoline), else a rigid barrel."""
    slot = [e for e in scene.active_effects() if getattr(e, "slot", None) == "collision"]
    if not slot:
        return RigidCollision(scene.bat.moi_kgm2)
    return slot[0].build(scene, random.Random(0))  # draws nothing at random


def true_metric(
    scene: Scene, locations_in: tuple[float, ...], metric: str = "bbcor", speed_m_s: float = BBCOR_SPEED_M_S
) -> Truth:
    """The scene's bat's true `metric` at each location (inches from the barrel end)."""
    bat, rig = scene.bat, scene.rig
    collision = collision_of(scene)
    out: dict[float, float] = {}
    for loc in locations_in:
        q = bat.length_m - rig.pivot_from_knob_m - loc * INCH
        e_a, _ = collision.collide(scene.ball, speed_m_s, q)
        m = compute_metrics(speed_m_s, e_a * speed_m_s, q, bat.moi_kgm2, scene.ball.m1, bat.length_m)
        out[float(loc)] = float(getattr(m, metric))
    return Truth(metric, speed_m_s, out)
