"""The collision model's prediction of BESR, BBS and BBCOR against hoop frequency.

e_A from rig.physics.predict_bat (pivoted bat with the hoop mode, founding paper Eqs. 1-2), then
BBCOR, BESR and BBS from rig.measure.metrics.compute_metrics with the same e_A, as the rig would
compute them from a shot at `speed` m/s, the bat struck IMPACT_FROM_TIP_IN from the barrel end.
For a population the curve is the mean, at each hoop frequency, of the predictions for every
bat's own length and MOI (the population's medians, or defaults, where a bat gives none): the
metrics are not linear in MOI and length, so one "median bat" would sit off the population.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.units import INCH
from rig.measure.metrics import compute_metrics
from rig.physics import DEFAULT_PARAMS, CollisionParams, PivotedBat, predict_bat
from rig.population.dataset import METRICS, PopulationBat

SPEED_M_S = 60.8  # 136 mph: BESR/BBCOR relative speed
BALL_MASS_KG = 0.145
IMPACT_FROM_TIP_IN = 6.0
DEFAULT_LENGTH_IN = 33.0
DEFAULT_MOI_KGM2 = 0.19

HoopGrid = Sequence[float] | np.ndarray  # hoop frequencies, Hz: a list, or grid_for()'s array


@dataclass(frozen=True)
class ReferenceBat:
    """The bat the model curve is computed for."""

    length_in: float
    moi_kgm2: float
    impact_from_pivot_m: float

    @classmethod
    def of(cls, bats: Sequence[PopulationBat]) -> ReferenceBat:
        """Median length and MOI of the population (defaults where it gives none)."""
        lengths = [b.length_in for b in bats if b.length_in is not None]
        mois = [b.moi_kgm2 for b in bats if b.moi_kgm2 is not None]
        length = statistics.median(lengths) if lengths else DEFAULT_LENGTH_IN
        moi = statistics.median(mois) if mois else DEFAULT_MOI_KGM2
        return cls.at(length, moi)

    @classmethod
    def at(cls, length_in: float, moi_kgm2: float, location_in: float = IMPACT_FROM_TIP_IN) -> ReferenceBat:
        """A bat of this length and MOI, struck `location_in` from the barrel end."""
        q = length_in * INCH - PIVOT_FROM_KNOB_M - location_in * INCH
        return cls(length_in, moi_kgm2, q)


PAPER_PARAMS = DEFAULT_PARAMS.model_copy(update={"m1": BALL_MASS_KG})


def predict_metrics(
    hoop_hz: float, bat: ReferenceBat, speed: float = SPEED_M_S, params: CollisionParams = PAPER_PARAMS
) -> dict[str, float]:
    """e_a, besr, bbs and bbcor the model (the paper's constants unless given) predicts for `bat`."""
    pivoted = PivotedBat(moi_kgm2=bat.moi_kgm2, impact_from_pivot_m=bat.impact_from_pivot_m)
    e_a = predict_bat(params, speed, hoop_hz, pivoted).e_a
    m = compute_metrics(
        speed, e_a * speed, bat.impact_from_pivot_m, bat.moi_kgm2, BALL_MASS_KG, bat.length_in * INCH
    )
    return {"e_a": e_a, **{name: m.value(name) for name in METRICS}}


def model_curves(
    hoop_hz: HoopGrid,
    bat: ReferenceBat,
    speed: float = SPEED_M_S,
    params: CollisionParams = PAPER_PARAMS,
) -> dict[str, list[float]]:
    """predict_metrics over a grid of hoop frequencies."""
    rows = [predict_metrics(float(f), bat, speed, params) for f in hoop_hz]
    out: dict[str, list[float]] = {"hoop_hz": [float(f) for f in hoop_hz]}
    for key in ("e_a", *METRICS):
        out[key] = [r[key] for r in rows]
    return out


def population_curves(
    bats: Sequence[PopulationBat],
    hoop_hz: HoopGrid,
    speed: float = SPEED_M_S,
    params: CollisionParams = PAPER_PARAMS,
    location_in: float | None = None,
) -> dict[str, list[float]]:
    """At each hoop frequency, the mean of predict_metrics over the bats' own length and MOI.

    Struck IMPACT_FROM_TIP_IN from the end; with `location_in`, at each bat's own location_in
    (where its certification found the maximum), else at `location_in`.
    """
    fallback = ReferenceBat.of(bats)

    def where(b: PopulationBat) -> float:
        if location_in is None:
            return IMPACT_FROM_TIP_IN
        return location_in if b.location_in is None else b.location_in

    refs = [
        ReferenceBat.at(b.length_in or fallback.length_in, b.moi_kgm2 or fallback.moi_kgm2, where(b))
        for b in bats
    ] or [fallback]
    curves = [model_curves(hoop_hz, ref, speed, params) for ref in refs]
    out: dict[str, list[float]] = {"hoop_hz": [float(f) for f in hoop_hz]}
    for key in ("e_a", *METRICS):
        out[key] = [float(v) for v in np.mean([c[key] for c in curves], axis=0)]
    return out


def grid_for(hoops: Sequence[float], step_hz: float = 25.0) -> np.ndarray:
    """An even grid covering the population's hoop frequencies with half a bin to spare."""
    lo = max(step_hz, np.floor((min(hoops) - 50.0) / step_hz) * step_hz)
    hi = np.ceil((max(hoops) + 50.0) / step_hz) * step_hz
    return np.arange(lo, hi + 0.5 * step_hz, step_hz)
