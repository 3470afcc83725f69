"""What a calibration file may say: checked as strictly as a bat file.

Each parameter within the fit's own bounds, each uncertainty and the scatter a standard deviation
no wider than the range it is about, a covariance that is one (symmetric, positive semi-definite,
its diagonal the uncertainties squared), model constants that are the parameters' and the ball's
own, a ball of physical constants, and a provenance with degrees of freedom. The first problem is
a ParameterError naming the field (rig.population.calfile turns it into one line naming the file).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

from rig.core.bat import HOOP_HZ
from rig.core.errors import ParameterError
from rig.measure.registry import metric
from rig.physics import CollisionParams
from rig.physics.ball_law import BALL_NAMES
from rig.physics.params import check_physical
from rig.population.calibrate import BOUNDS, PAPER_BASE, UNITS, model_params
from rig.population.limits import MIN_BATS


class _Provenance(Protocol):
    """What the check reads of a calibration's provenance."""

    @property
    def n_bats(self) -> int: ...
    @property
    def hoop_min_hz(self) -> float: ...
    @property
    def hoop_max_hz(self) -> float: ...


class Calibration(Protocol):
    """What the check reads of a calibration (rig.population.calfile.CalibrationFile has it): a
    protocol, so that the file's model, which runs the check, is not imported back here."""

    @property
    def metric(self) -> str: ...
    @property
    def speed_m_s(self) -> float: ...
    @property
    def default_location_in(self) -> float: ...
    @property
    def parameters(self) -> dict[str, float]: ...
    @property
    def uncertainty(self) -> dict[str, float]: ...
    @property
    def covariance(self) -> list[list[float]]: ...
    @property
    def scatter(self) -> float: ...
    @property
    def loo_rmse(self) -> float: ...
    @property
    def model_params(self) -> CollisionParams: ...
    @property
    def ball(self) -> dict[str, Any] | None: ...
    @property
    def provenance(self) -> _Provenance: ...


SPEED_RANGE = (1.0, 100.0)  # m/s, as every speed a user gives
BALL_MASS_RANGE_KG = (0.1, 0.25)  # a baseball (0.142-0.149 kg) to a 12 in softball (0.177-0.198 kg)
LOCATION_MAX_IN = 36.0  # an impact location is on the bat: at most 36 in from the tip, as a scan's
REL_TOL = 1e-6  # an uncertainty against sqrt(variance), model constants against the parameters'
PSD_TOL = 1e-9  # the correlation matrix's eigenvalues may fall this far below 0 (round-off)


def check_calibration(cal: Calibration) -> None:
    """ParameterError naming the first field of `cal` that no calibration can have."""
    _within("speed_m_s", cal.speed_m_s, *SPEED_RANGE, "m/s")
    if not 0.0 < cal.default_location_in <= LOCATION_MAX_IN:
        raise ParameterError(
            "default_location_in",
            cal.default_location_in,
            f"must lie within 0-{LOCATION_MAX_IN:g} in (not 0)",
        )
    for name, value in cal.parameters.items():
        _within(f"parameters.{name}", value, *BOUNDS[name], UNITS[name])
    if list(cal.uncertainty) != list(cal.parameters):
        raise ParameterError("uncertainty", sorted(cal.uncertainty), f"must name {', '.join(cal.parameters)}")
    for name, value in cal.uncertainty.items():
        low, high = BOUNDS[name]
        _within(f"uncertainty.{name}", value, 0.0, high - low, UNITS[name])
    span = metric_span(cal.metric)
    _within("scatter", cal.scatter, 0.0, span, cal.metric)
    _within("loo_rmse", cal.loo_rmse, 0.0, span, cal.metric)
    _covariance(np.array(cal.covariance, dtype=float), cal.uncertainty)
    base = _ball(cal.ball)
    if cal.ball is None:  # the paper's ball at the runs' ball mass (a baseball, a softball)
        _within("model_params.m1", cal.model_params.m1, *BALL_MASS_RANGE_KG, "kg")
        base = base.model_copy(update={"m1": cal.model_params.m1})
    _model_params(cal.model_params, model_params(cal.parameters, base))
    _provenance(cal)


def metric_span(name: str) -> float:
    """The width of a metric's scale, its registry limit range (BBS's in m/s): no scatter about a
    model can be wider."""
    low, high = metric(name).limit_range
    return high - low


def _within(name: str, value: float, low: float, high: float, unit: str) -> None:
    if not low <= value <= high:  # also refuses nan
        raise ParameterError(name, value, f"must lie within {low:g}-{high:g} {unit}".rstrip())


def _covariance(c: np.ndarray, uncertainty: Mapping[str, float]) -> None:
    """A covariance: variances >= 0 whose roots are the uncertainties, symmetric, PSD."""
    variances = np.diag(c)
    for i, (name, u) in enumerate(uncertainty.items()):
        if variances[i] < 0.0:
            raise ParameterError(f"covariance[{i}][{i}]", float(variances[i]), "a variance is never negative")
        root = math.sqrt(variances[i])
        if not math.isclose(u, root, rel_tol=REL_TOL, abs_tol=1e-300):
            raise ParameterError(f"uncertainty.{name}", u, f"is not sqrt(covariance[{i}][{i}]) = {root:.6g}")
    scale = np.sqrt(np.outer(variances, variances))
    if np.any(np.abs(c - c.T) > PSD_TOL * scale):
        raise ParameterError("covariance", "not symmetric", "covariance[i][j] must equal covariance[j][i]")
    if np.any((scale == 0.0) & (c != 0.0)):
        raise ParameterError("covariance", "a covariance with a zero variance", "not positive semi-definite")
    corr = np.divide(c, scale, out=np.zeros_like(c), where=scale > 0.0)
    lowest = float(np.linalg.eigvalsh(0.5 * (corr + corr.T))[0])
    if lowest < -PSD_TOL:
        raise ParameterError(
            "covariance", f"a correlation eigenvalue of {lowest:.3g}", "not positive semi-definite"
        )


def _ball(ball: Mapping[str, Any] | None) -> CollisionParams:
    """The ball's constants the calibration solved with (its recorded ball's, else the paper's)."""
    if ball is None:
        return PAPER_BASE
    constants = ball.get("constants")
    if not isinstance(constants, dict) or set(constants) != set(BALL_NAMES):
        raise ParameterError("ball.constants", constants, f"must be exactly {', '.join(BALL_NAMES)}")
    if not all(isinstance(v, int | float) and math.isfinite(v) for v in constants.values()):
        raise ParameterError("ball.constants", constants, "must be finite numbers")
    try:
        return check_physical(PAPER_BASE.model_copy(update=constants))
    except ParameterError as exc:
        raise ParameterError(f"ball.constants.{exc.name}", exc.value, exc.reason) from None


def _model_params(stated: CollisionParams, expected: CollisionParams) -> None:
    """The file's model constants are those its parameters and ball give."""
    for name in type(stated).model_fields:
        x, y = getattr(stated, name), getattr(expected, name)
        if not math.isclose(x, y, rel_tol=REL_TOL, abs_tol=1e-300):
            raise ParameterError(
                f"model_params.{name}", x, f"is not {y:.6g}, what the parameters and the ball give"
            )


def _provenance(cal: Calibration) -> None:
    prov = cal.provenance
    least = max(MIN_BATS, len(cal.parameters) + 1)
    if prov.n_bats < least:
        raise ParameterError("provenance.n_bats", prov.n_bats, f"a calibration needs at least {least} bats")
    _within("provenance.hoop_min_hz", prov.hoop_min_hz, *HOOP_HZ, "Hz")
    _within("provenance.hoop_max_hz", prov.hoop_max_hz, *HOOP_HZ, "Hz")
    if prov.hoop_max_hz < prov.hoop_min_hz:
        raise ParameterError(
            "provenance.hoop_max_hz", prov.hoop_max_hz, f"is below hoop_min_hz {prov.hoop_min_hz:g}"
        )
