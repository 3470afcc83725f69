"""A simulated lab's bat population as the cross-check sees it: true and measured metrics.

Studies of the cross-check's power need hundreds of bats (benchmarks/bench_crosscheck.py).
Certifying each on the simulated rig takes about half a second of solves per shot series, so the
study takes a bat's certified value as what the simulated rig would centre on: the scene's own
collision (the `collision` slot effect, i.e. the trampoline with the scene's true barrel, the bat's
own offset and any alteration) at the impact location, plus Gaussian measurement noise of a stated
size (benchmarks/bench_simpop.py measures that size on real simulated certifications). Only the
effects the cross-check is about enter: the barrel, the bat's offset, the noise of a certified mean.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rig.core.bat import Barrel
from rig.core.units import INCH
from rig.measure.metrics import compute_metrics
from rig.population.dataset import PopulationBat
from rig.simulators.effects.trampoline import TrampolineConfig
from rig.simulators.physics import Collision
from rig.simulators.scene import Scene
from studies.population.simulated import SimulatedBat

SPEED_M_S = 60.8  # the BBCOR inbound speed the calibration predicts at
# The BBCOR procedure's scan (protocols/bbcor.toml): 5.0-7.5 in by 0.5 in, extended by up to 1 in
# when the maximum sits at an end of it.
SCAN_IN = (5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0, 8.5)


@dataclass(frozen=True)
class Variation:
    """Bat-to-bat variation of the barrel the one-mode calibration cannot see: each bat's contact
    stiffness (k1 scale) and hoop mass m2 times 1 + U(-rel, rel), drawn from the scene seed and the
    bat's id (the same for a bat and its altered twin)."""

    k1_rel: float = 0.0
    m2_rel: float = 0.0

    def apply(self, scene: Scene, bat_id: str) -> Scene:
        """The scene with this bat's own k1 scale and m2."""
        if not (self.k1_rel or self.m2_rel):
            return scene
        t = next(e for e in scene.effects if isinstance(e, TrampolineConfig))
        draw = random.Random(f"{scene.seed}/barrel-variation/{bat_id}")
        k1 = t.k1_scale * (1.0 + draw.uniform(-self.k1_rel, self.k1_rel))
        m2 = (t.m2 or scene.ball.m2) * (1.0 + draw.uniform(-self.m2_rel, self.m2_rel))
        return scene.with_effect("trampoline", k1_scale=k1, m2=m2)


def bat_scene(scene: Scene, bat: SimulatedBat, vary: Variation | None = None) -> Scene:
    """The scene with this bat's true properties (true MOI) and its alteration, as a certification has it."""
    s = bat.spec
    if vary is not None:
        scene = vary.apply(scene, s.id)
    out = scene.with_bat(
        id=s.id,
        length_m=s.length_m,
        mass_kg=s.mass_kg,
        moi_kgm2=bat.moi_kgm2,
        hoop_hz=s.hoop_hz,
        balance_point_m=s.balance_point_in * INCH if s.balance_point_in is not None else None,
    )
    return out.with_alteration(bat.alteration_bbcor) if bat.altered else out


def bat_metric(
    scene: Scene, bat: SimulatedBat, metric: str = "bbcor", vary: Variation | None = None
) -> Callable[[float], float]:
    """The metric the simulated rig's collision gives this bat, as a function of the location from
    the barrel end: the bat's scene and collision effect built once (the effect caches its solves)."""
    sc = bat_scene(scene, bat, vary)
    slot = [e for e in sc.active_effects() if getattr(e, "slot", None) == "collision"]
    if not slot:
        raise ValueError(f"scene {scene.name!r} has no collision effect: its barrel is rigid")
    effect: Collision = slot[0].build(sc, random.Random(0))  # the collision draws nothing at random

    def at(location_in: float) -> float:
        q = (bat.spec.length_in - location_in) * INCH - sc.rig.pivot_from_knob_m
        e_a, _ = effect.collide(sc.ball, SPEED_M_S, q)
        m = compute_metrics(SPEED_M_S, e_a * SPEED_M_S, q, bat.moi_kgm2, sc.ball.m1, bat.spec.length_m)
        return float(getattr(m, metric))

    return at


def true_metric(scene: Scene, bat: SimulatedBat, location_in: float, metric: str = "bbcor") -> float:
    """The metric the simulated rig's collision gives this bat at `location_in` from the barrel end."""
    return bat_metric(scene, bat, metric)(location_in)


def best_scan_location(at: Callable[[float], float]) -> float:
    """The scan location (SCAN_IN) where `at` (a bat's metric by location) is largest."""
    return max(SCAN_IN, key=at)


def scan_maximum(scene: Scene, bat: SimulatedBat, metric: str = "bbcor") -> float:
    """The scan location (SCAN_IN) where the bat's true metric is largest: where a scan ends up."""
    return best_scan_location(bat_metric(scene, bat, metric))


def measured_population(
    scene: Scene,
    bats: Sequence[SimulatedBat],
    location_in: float | Callable[[Callable[[float], float]], float],
    noise_sd: float,
    rng: np.random.Generator,
    metric: str = "bbcor",
    u: float | None = None,
    vary: Variation | None = None,
) -> list[PopulationBat]:
    """Population rows: each bat's true metric plus N(0, noise_sd); u_<metric> = u (else noise_sd).

    `location_in` is a location from the barrel end, or a function choosing one from the bat's
    metric by location (best_scan_location: where the procedure's scan would settle). `vary`
    gives each bat its own barrel (Variation).
    """
    rows = []
    for bat in bats:
        at = bat_metric(scene, bat, metric, vary)
        loc = location_in(at) if callable(location_in) else location_in
        value = at(loc) + float(rng.normal(0.0, noise_sd))
        rows.append(
            PopulationBat.model_validate(
                {
                    "bat_id": bat.spec.id,
                    "barrel": Barrel.ALUMINIUM,
                    "hoop_hz": bat.spec.hoop_hz,
                    "length_in": bat.spec.length_in,
                    "weight_oz": bat.spec.weight_oz,
                    "moi_kgm2": bat.moi_kgm2,
                    "location_in": loc,
                    metric: value,
                    f"u_{metric}": noise_sd if u is None else u,
                    "source": f"simulated ({scene.name} scene, measured value = true + noise)",
                }
            )
        )
    return rows
