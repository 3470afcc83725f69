"""A field screen from a bat's hoop frequency: the calibrated prediction with its interval, never a verdict.

The bat model is a bat of the calibration's population (`model_id` its `bat_id`): the sample the lab
tested, whose MOI, length and impact location the calibration file records (files written before
they were recorded are refused, naming the cause) and whose hoop frequency is the model's lab
value F0 unless one is given. At the screened bat's hoop frequency f the prediction and its
interval are the cross-check's (rig.population.crosscheck: the calibrated model, the parameters'
covariance, the bat-to-bat scatter, Student-t with n - p degrees of freedom), widened by f's own
uncertainty when f was measured (u_f carried by the prediction's slope, by central differences):
  u = sqrt(u_model^2 + u_scatter^2 + (dP/df u_f)^2),  interval = P +- t u.
Against the limit: whether P exceeds it, and whether the interval lies above, below or across it.
The fall of the hoop frequency, F0 - f, in Hz and per cent of F0 (F0's own uncertainty is not
recorded, so the fall's u is f's alone). Sources find hoop frequency strongly correlated with
performance but publish no prediction error for it (docs/screening.md): a screen is a reason to
send a bat to the lab, never a finding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from rig.core.bat import HOOP_HZ, PIVOT_FROM_KNOB_M
from rig.core.errors import ConfigError
from rig.core.units import INCH
from rig.population.calfile import CalibrationFile
from rig.population.crosscheck import CrossCheck, crosscheck_at

SLOPE_STEP = 0.005  # of f: the central-difference step for dP/df
STATEMENT = (
    "a screen, not a certification: it predicts from the hoop frequency alone; only a test on the rig"
    " to a procedure measures the bat"
)


class ScreenRefused(ConfigError):
    """The bat cannot be screened against this calibration; the message names the cause."""


@dataclass(frozen=True)
class BatModel:
    """A bat model as its calibration records it: its tested sample's geometry and hoop frequency."""

    model_id: str
    hoop_hz: float
    moi_kgm2: float
    length_in: float
    location_in: float

    @property
    def impact_from_pivot_m(self) -> float:
        """Q: pivot (6 in from the knob) to the impact location, m."""
        return (self.length_in - self.location_in) * INCH - PIVOT_FROM_KNOB_M


def bat_model(cal: CalibrationFile, model_id: str, source: str = "") -> BatModel:
    """The calibration's bat `model_id`; ScreenRefused when it is absent or lacks its geometry."""
    rows = [b for b in cal.bats if b.get("bat_id") == model_id]
    if not rows:
        known = [str(b.get("bat_id")) for b in cal.bats]
        shown = ", ".join(known[:8]) + (f" ... ({len(known)} in all)" if len(known) > 8 else "")
        raise ScreenRefused(f"no bat model {model_id!r} in the calibration; its bats: {shown}", source=source)
    row = rows[0]
    missing = [k for k in ("hoop_hz", "moi_kgm2", "length_in", "location_in") if k not in row]
    if missing:
        raise ScreenRefused(
            f"bat {model_id} has no {', '.join(missing)} in the calibration file (written before they were"
            " recorded, or the population gave no length): calibrate again with `rig model calibrate`",
            source=source,
        )
    try:
        values = {k: float(row[k]) for k in ("hoop_hz", "moi_kgm2", "length_in", "location_in")}
    except (TypeError, ValueError):
        raise ScreenRefused(
            f"bat {model_id}: a non-numeric value in the calibration file", source=source
        ) from None
    if not all(math.isfinite(v) for v in values.values()):
        raise ScreenRefused(f"bat {model_id}: a non-finite value in the calibration file", source=source)
    return BatModel(model_id, **values)


@dataclass(frozen=True)
class Screen:
    """A screening result: the prediction, its interval, the limit and the hoop frequency's fall."""

    model_id: str
    metric: str
    hoop_hz: float
    u_hoop_hz: float  # standard uncertainty of f (0: given as a number)
    hoop_source: str
    model_hoop_hz: float  # F0, the model's hoop frequency in the lab
    model_hoop_source: str
    predicted: float
    interval: tuple[float, float]
    coverage: float
    u_model: float
    u_scatter: float
    u_from_hoop: float  # dP/df u_f
    slope_per_hz: float  # dP/df
    t_factor: float
    dof: int
    limit: float
    limit_source: str
    extrapolated: bool
    notes: tuple[str, ...] = field(default=())

    @property
    def u_total(self) -> float:
        """sqrt(u_model^2 + u_scatter^2 + u_from_hoop^2)."""
        return math.sqrt(self.u_model**2 + self.u_scatter**2 + self.u_from_hoop**2)

    @property
    def fall_hz(self) -> float:
        """F0 - f: how far the hoop frequency has fallen (negative: risen)."""
        return self.model_hoop_hz - self.hoop_hz

    @property
    def fall_percent(self) -> float:
        """The fall in per cent of F0."""
        return 100.0 * self.fall_hz / self.model_hoop_hz

    @property
    def predicted_exceeds_limit(self) -> bool:
        """Whether the prediction itself lies above the limit."""
        return self.predicted > self.limit

    @property
    def interval_vs_limit(self) -> str:
        """'above' (the whole interval exceeds the limit), 'below' (none of it does) or 'across'."""
        if self.interval[0] > self.limit:
            return "above"
        return "below" if self.interval[1] <= self.limit else "across"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "kind": "screen",
            "statement": STATEMENT,
            "model_id": self.model_id,
            "metric": self.metric,
            "hoop_hz": self.hoop_hz,
            "hoop_u_hz": self.u_hoop_hz,
            "hoop_source": self.hoop_source,
            "model_hoop_hz": self.model_hoop_hz,
            "model_hoop_source": self.model_hoop_source,
            "hoop_fall_hz": self.fall_hz,
            "hoop_fall_percent": self.fall_percent,
            "hoop_fall_u_hz": self.u_hoop_hz,
            "predicted": self.predicted,
            "interval": list(self.interval),
            "coverage": self.coverage,
            "u_model": self.u_model,
            "u_scatter": self.u_scatter,
            "u_from_hoop": self.u_from_hoop,
            "u_total": self.u_total,
            "slope_per_hz": self.slope_per_hz,
            "t_factor": self.t_factor,
            "dof": self.dof,
            "limit": self.limit,
            "limit_source": self.limit_source,
            "predicted_exceeds_limit": self.predicted_exceeds_limit,
            "interval_vs_limit": self.interval_vs_limit,
            "extrapolated": self.extrapolated,
            "notes": list(self.notes),
        }


def _at(cal: CalibrationFile, model: BatModel, hoop_hz: float, coverage: float) -> CrossCheck:
    q = model.impact_from_pivot_m
    return crosscheck_at(
        cal, hoop_hz, model.moi_kgm2, q, model.length_in, None, None, coverage, model.model_id
    )


def screen(
    cal: CalibrationFile,
    model: BatModel,
    hoop_hz: float,
    limit: float,
    *,
    u_hoop_hz: float = 0.0,
    hoop_source: str = "given",
    model_hoop_hz: float | None = None,
    limit_source: str = "given",
    coverage: float = 0.95,
) -> Screen:
    """Screen a bat of `model` whose hoop frequency is `hoop_hz` (u_hoop_hz its standard uncertainty)."""
    centre = _at(cal, model, hoop_hz, coverage)
    h = SLOPE_STEP * hoop_hz
    lo, hi = max(hoop_hz - h, HOOP_HZ[0]), min(hoop_hz + h, HOOP_HZ[1])
    slope = (_at(cal, model, hi, coverage).predicted - _at(cal, model, lo, coverage).predicted) / (hi - lo)
    u_from_hoop = abs(slope) * u_hoop_hz
    u = math.sqrt(centre.u_model**2 + centre.u_scatter**2 + u_from_hoop**2)
    t = centre.t_factor
    notes = []
    if centre.extrapolated:
        notes.append(
            f"outside the calibrated range ({cal.provenance.range_text()}): predicted by extrapolation"
        )
    f0 = model.hoop_hz if model_hoop_hz is None else model_hoop_hz
    return Screen(
        model_id=model.model_id,
        metric=cal.metric,
        hoop_hz=hoop_hz,
        u_hoop_hz=u_hoop_hz,
        hoop_source=hoop_source,
        model_hoop_hz=f0,
        model_hoop_source="calibration file" if model_hoop_hz is None else "given",
        predicted=centre.predicted,
        interval=(centre.predicted - t * u, centre.predicted + t * u),
        coverage=coverage,
        u_model=centre.u_model,
        u_scatter=centre.u_scatter,
        u_from_hoop=u_from_hoop,
        slope_per_hz=slope,
        t_factor=t,
        dof=centre.dof,
        limit=limit,
        limit_source=limit_source,
        extrapolated=centre.extrapolated,
        notes=tuple(notes),
    )
