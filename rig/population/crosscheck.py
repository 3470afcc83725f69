"""The calibrated cross-check: each bat's measured metric against the calibrated model's prediction.

The prediction is the calibration's own fitted model (rig.population.calibrate.predict at the
file's parameters), at the bat's hoop frequency, MOI, length and impact location. Its standard
uncertainty has three independent parts:
  u_model    the fitted parameters' covariance carried to this bat by the delta method
             (u^2 = g^T C g, g the prediction's gradient in the parameters at this bat, by
             central differences of the same prediction code);
  u_scatter  the bat-to-bat scatter the calibration left, s = sqrt(SSR / (n - p));
  u_measured this bat's own measurement standard uncertainty (k = 1; 0 when not known).
The prediction interval is predicted +- t sqrt(u_model^2 + u_scatter^2 + u_measured^2), t the
Student-t quantile at (1 + coverage) / 2 with the calibration's n - p degrees of freedom (the
scatter is estimated from n - p residuals). z = (measured - predicted) / sqrt(...); a bat is
flagged when its measured value lies outside the interval. A bat outside the calibration's hoop
(or MOI) range is still predicted, marked `extrapolated`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.errors import ConfigError
from rig.core.units import INCH
from rig.measure.registry import metric
from rig.measure.student import quantile as t_quantile
from rig.physics import PivotedBat
from rig.population.calfile import CalibrationFile, calibration_base, covariance_matrix
from rig.population.calibrate import BOUNDS, FitBat, metric_line, predict_many
from rig.population.dataset import PopulationBat, missing_column

GRADIENT_STEP = 0.05  # of each parameter's sigma: the delta method's central-difference step


class CrossCheckRefused(ConfigError):
    """A bat cannot be cross-checked against this calibration; the message names the cause."""


@dataclass(frozen=True)
class CrossCheck:
    """One bat's prediction, prediction interval, measured value and verdict."""

    bat_id: str
    predicted: float
    measured: float | None
    interval: tuple[float, float]  # prediction interval at `coverage`
    u_model: float  # parameter covariance, delta method at this bat
    u_scatter: float  # the calibration's bat-to-bat scatter
    u_measured: float  # this bat's own measurement standard uncertainty (0: not known)
    z: float | None
    flagged: bool | None
    coverage: float
    metric: str = "bbcor"
    hoop_hz: float = math.nan
    t_factor: float = math.nan  # the Student-t quantile the interval uses
    dof: int = 0
    extrapolated: bool = False  # hoop frequency or MOI outside the calibration's range
    u_measured_known: bool = True
    u_ball_cor: float = 0.0  # a BPF's: the prediction BBCOR / COR carries the ball COR's u once

    @property
    def u_total(self) -> float:
        """sqrt(u_model^2 + u_scatter^2 + u_measured^2 + u_ball_cor^2)."""
        return math.sqrt(self.u_model**2 + self.u_scatter**2 + self.u_measured**2 + self.u_ball_cor**2)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: bat_id, predicted, measured, interval, flagged, z and the uncertainty's parts."""
        return {
            "bat_id": self.bat_id,
            "metric": self.metric,
            "hoop_hz": self.hoop_hz,
            "predicted": self.predicted,
            "measured": self.measured,
            "interval": list(self.interval),
            "coverage": self.coverage,
            "z": self.z,
            "flagged": self.flagged,
            "u_model": self.u_model,
            "u_scatter": self.u_scatter,
            "u_measured": self.u_measured,
            "u_measured_known": self.u_measured_known,
            "u_ball_cor": self.u_ball_cor,
            "u_total": self.u_total,
            "t_factor": self.t_factor,
            "dof": self.dof,
            "extrapolated": self.extrapolated,
        }


def dof(cal: CalibrationFile) -> int:
    """The calibration's residual degrees of freedom n - p."""
    return cal.provenance.n_bats - len(cal.parameters)


def t_factor(cal: CalibrationFile, coverage: float) -> float:
    """Student-t quantile at (1 + coverage)/2 with n - p degrees of freedom."""
    if not 0.0 < coverage < 1.0:
        raise CrossCheckRefused(f"coverage {coverage:g} must lie between 0 and 1")
    if dof(cal) < 1:
        raise CrossCheckRefused(f"calibration has {dof(cal)} degrees of freedom: no interval")
    # rig.measure.student, not scipy.stats: importing scipy.stats took half the command's time
    return t_quantile(0.5 * (1.0 + coverage), dof(cal))


def _q(bat_id: str, length_in: float, location_in: float) -> float:
    q = (length_in - location_in) * INCH - PIVOT_FROM_KNOB_M
    if q <= 0.05:
        raise CrossCheckRefused(f"bat {bat_id}: impact {location_in:g} in from the end is off the barrel")
    return q


def _row(cal: CalibrationFile, bat_id: str, hoop_hz: float, moi: float, q: float, length_in: float) -> FitBat:
    """The bat as the calibration's prediction code takes it (the same geometry, speed and ball as
    its fit): the line of the quantity it fitted."""
    alpha, beta = metric_line(cal.fitted_metric, q, moi, length_in * INCH, ball_mass_kg=cal.model_params.m1)
    pivoted = PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)
    if pivoted.effective_mass <= cal.model_params.m2:
        raise CrossCheckRefused(
            f"bat {bat_id}: I/Q^2 = {pivoted.effective_mass:.3g} kg is below the calibrated m2"
            f" = {cal.model_params.m2:.3g} kg"
        )
    return FitBat(bat_id, hoop_hz, pivoted, alpha, beta, math.nan, speed_m_s=cal.speed_m_s)


@dataclass(frozen=True)
class _ToMetric:
    """From the fitted quantity to the calibration's metric at one bat: metric = a + r (fitted - b)
    (the same e_A on two lines; identity where the calibration fitted the metric itself), and the
    ball COR's u a BPF's prediction carries (k = 1)."""

    a: float = 0.0
    r: float = 1.0
    b: float = 0.0
    u_cor: float = 0.0  # u(COR) / COR: times the predicted BPF, its u from the ball COR

    def value(self, fitted: float) -> float:
        return self.a + self.r * (fitted - self.b)


def _to_metric(
    cal: CalibrationFile, row: FitBat, length_in: float, ball_cor: tuple[float, float] | None
) -> _ToMetric:
    if cal.fitted_metric == cal.metric:
        return _ToMetric()
    needs_cor = metric(cal.metric).needs_ball_cor
    if needs_cor and ball_cor is None:
        raise CrossCheckRefused(
            f"a {cal.metric} prediction needs the run's ball COR (BPF = BBCOR / ball COR): cross-check it"
            " in rig certify --ball-lot LOT"
        )
    cor, u_cor = ball_cor if needs_cor and ball_cor is not None else (None, 0.0)
    q, moi, m1 = row.pivoted.impact_from_pivot_m, row.pivoted.moi_kgm2, cal.model_params.m1
    a, slope = metric_line(cal.metric, q, moi, length_in * INCH, ball_mass_kg=m1, ball_cor=cor)
    return _ToMetric(a, slope / row.beta, row.alpha, 0.0 if cor is None else u_cor / cor)


def _steps(
    cal: CalibrationFile, rows: Sequence[FitBat]
) -> list[tuple[dict[str, float], dict[str, float], float]]:
    """For each parameter: the values one step up, one step down, and the span between them.

    m2 never steps past any checked bat's own I/Q^2 (the model has no barrel heavier than the bat).
    """
    cov = covariance_matrix(cal)
    out = []
    for i, name in enumerate(cal.parameters):
        x = cal.parameters[name]
        h = GRADIENT_STEP * math.sqrt(max(cov[i, i], 0.0)) or 1e-6 * max(abs(x), 1.0)
        lo, hi = BOUNDS[name]
        if name == "m2":
            hi = min(hi, 0.5 * (x + min(r.pivoted.effective_mass for r in rows)))
        up, down = min(x + h, hi), max(x - h, lo)  # one-sided at a bound
        out.append(({**cal.parameters, name: up}, {**cal.parameters, name: down}, up - down))
    return out


def _predict(cal: CalibrationFile, rows: Sequence[FitBat]) -> tuple[np.ndarray, np.ndarray]:
    """Predictions and u_model for each row, in one batch of solves (centre and +-step per parameter)."""
    steps = _steps(cal, rows)
    sets = [dict(cal.parameters)] + [s for up, down, _ in steps for s in (up, down)]
    values = predict_many(rows, sets, base=calibration_base(cal), numpy_lanes=True)  # no numba to load
    centre = values[0]
    grad = np.array([(values[1 + 2 * i] - values[2 + 2 * i]) / span for i, (_, _, span) in enumerate(steps)])
    cov = covariance_matrix(cal)
    u_model = np.sqrt(np.maximum(np.einsum("ib,ij,jb->b", grad, cov, grad), 0.0))
    return centre, u_model


def _check(
    cal: CalibrationFile,
    row: FitBat,
    predicted: float,
    u_model: float,
    measured: float | None,
    u_measured: float | None,
    coverage: float,
    to: _ToMetric | None = None,
) -> CrossCheck:
    """`predicted` and `u_model` of the quantity fitted; `to` carries them to the metric."""
    to = to or _ToMetric()
    t = t_factor(cal, coverage)
    predicted, u_model, scatter = to.value(predicted), abs(to.r) * u_model, abs(to.r) * cal.scatter
    u_cor = abs(predicted) * to.u_cor
    u_meas = 0.0 if u_measured is None else float(u_measured)
    u = math.sqrt(u_model**2 + scatter**2 + u_meas**2 + u_cor**2)
    z = None if measured is None else (measured - predicted) / u
    prov = cal.provenance
    return CrossCheck(
        bat_id=row.bat_id,
        predicted=predicted,
        measured=measured,
        interval=(predicted - t * u, predicted + t * u),
        u_model=u_model,
        u_scatter=scatter,
        u_measured=u_meas,
        z=z,
        flagged=None if z is None else abs(z) > t,
        coverage=coverage,
        metric=cal.metric,
        hoop_hz=row.hoop_hz,
        t_factor=t,
        dof=dof(cal),
        extrapolated=not prov.covers(row.hoop_hz, row.pivoted.moi_kgm2),
        u_measured_known=u_measured is not None,
        u_ball_cor=u_cor,
    )


def crosscheck_one(
    cal: CalibrationFile,
    hoop_hz: float,
    moi_kgm2: float,
    length_in: float,
    location_in: float | None,
    measured: float | None,
    u_measured: float | None,
    coverage: float = 0.95,
    bat_id: str = "bat",
) -> CrossCheck:
    """One bat's cross-check (location_in None: the calibration's default location)."""
    location = cal.default_location_in if location_in is None else location_in
    q = _q(bat_id, length_in, location)
    return crosscheck_at(cal, hoop_hz, moi_kgm2, q, length_in, measured, u_measured, coverage, bat_id)


def crosscheck_at(
    cal: CalibrationFile,
    hoop_hz: float,
    moi_kgm2: float,
    impact_from_pivot_m: float,
    length_in: float,
    measured: float | None,
    u_measured: float | None,
    coverage: float = 0.95,
    bat_id: str = "bat",
    ball_cor: tuple[float, float] | None = None,
) -> CrossCheck:
    """One bat's cross-check struck `impact_from_pivot_m` from the pivot (Q), as the rig records it.

    `ball_cor`: the run's ball COR and its standard u, which a BPF's prediction needs."""
    row = _row(cal, bat_id, hoop_hz, moi_kgm2, impact_from_pivot_m, length_in)
    to = _to_metric(cal, row, length_in, ball_cor)
    predicted, u_model = _predict(cal, [row])
    return _check(cal, row, float(predicted[0]), float(u_model[0]), measured, u_measured, coverage, to)


def check_population_metric(cal: CalibrationFile) -> None:
    """CrossCheckRefused unless a population file has a column for the calibration's metric."""
    if cal.fitted_metric != cal.metric:
        raise CrossCheckRefused(
            f"a {cal.metric} calibration fitted the runs' {cal.fitted_metric}; its cross-check is made in"
            " rig certify (a population file has no column for the metric)"
        )


def crosscheck_bats(
    cal: CalibrationFile,
    bats: Sequence[PopulationBat],
    coverage: float = 0.95,
    u_measured: Mapping[str, float] | None = None,
) -> list[CrossCheck]:
    """Every bat's cross-check, in one batch of solves.

    A bat's u_measured comes from `u_measured` by bat id, else from its row's `u_<metric>` column,
    else is unknown (0). CrossCheckRefused names the first bat lacking MOI or length.
    """
    t_factor(cal, coverage)
    check_population_metric(cal)
    if not bats:
        return []
    missing = missing_column(bats, ("moi_kgm2", "length_in"))
    if missing:
        raise CrossCheckRefused(missing)
    rows = []
    for b in bats:
        assert b.moi_kgm2 is not None and b.length_in is not None
        location = cal.default_location_in if b.location_in is None else b.location_in
        q = _q(b.bat_id, b.length_in, location)
        rows.append(_row(cal, b.bat_id, b.hoop_hz, b.moi_kgm2, q, b.length_in))
    predicted, u_model = _predict(cal, rows)
    out = []
    for b, row, p, um in zip(bats, rows, predicted, u_model, strict=True):
        u_meas = (u_measured or {}).get(b.bat_id)
        if u_meas is None:
            u_meas = b.u_metric(cal.metric)
        out.append(_check(cal, row, float(p), float(um), b.metric(cal.metric), u_meas, coverage))
    return out
