"""The population study (founding paper, section 5): Fig. 5 and Fig. 6 with the model overlaid.

Fig. 5: first hoop against first bending frequency, by barrel material.
Fig. 6: each metric (BESR, BBS, BBCOR) against hoop frequency, averaged in 50 Hz bins over
+-25 Hz (binning.py), beside the model's prediction for the population (rig.population.model).
The trend: a least-squares line through the bats' values (per 1000 Hz), the model's slope over the
same range, and Pearson's r.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rig.population.dataset import METRICS, PopulationBat
from rig.population.model import SPEED_M_S, HoopGrid, ReferenceBat, grid_for, population_curves
from studies.population.binning import Bin, bin_by_hoop

if TYPE_CHECKING:
    from rig.population.calfile import CalibrationFile

BIN_WIDTH_HZ = 50.0
HALF_WIDTH_HZ = 25.0


@dataclass(frozen=True)
class PopulationStudy:
    """Everything the plots and the JSON need."""

    bats: tuple[PopulationBat, ...]
    bins: dict[str, list[Bin]]
    model: dict[str, list[float]]
    reference: ReferenceBat
    trend: dict[str, dict[str, float | None]]
    sources: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())
    calibrated: dict[str, Any] | None = None  # the calibrated model's curve and where it came from

    @property
    def synthetic(self) -> bool:
        """True if any row is synthetic."""
        return any(b.synthetic for b in self.bats)

    def materials(self) -> dict[str, dict[str, Any]]:
        """Per barrel material: count, hoop range and span, mean first bending frequency."""
        out: dict[str, dict[str, Any]] = {}
        for material in sorted({b.barrel.value for b in self.bats}):
            group = [b for b in self.bats if b.barrel.value == material]
            hoops = [b.hoop_hz for b in group]
            bend = [b.bending_hz for b in group if b.bending_hz is not None]
            out[material] = {
                "n": len(group),
                "hoop_min_hz": min(hoops),
                "hoop_max_hz": max(hoops),
                "hoop_span_hz": max(hoops) - min(hoops),
                "hoop_std_hz": float(np.std(hoops, ddof=1)) if len(hoops) > 1 else None,
                "bending_mean_hz": float(np.mean(bend)) if bend else None,
            }
        return out

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the points of Fig. 5, the bins of Fig. 6, the model curve, the trends."""
        return {
            "synthetic": self.synthetic,
            "sources": list(self.sources),
            "notes": list(self.notes),
            "n_bats": len(self.bats),
            "materials": self.materials(),
            "fig5": [
                {
                    "bat_id": b.bat_id,
                    "barrel": b.barrel.value,
                    "hoop_hz": b.hoop_hz,
                    "bending_hz": b.bending_hz,
                }
                for b in self.bats
            ],
            "fig6": {
                "bin_width_hz": BIN_WIDTH_HZ,
                "half_width_hz": HALF_WIDTH_HZ,
                "metrics": {name: [b.as_dict() for b in bins] for name, bins in self.bins.items()},
            },
            "model": {
                **self.model,
                "speed_m_s": SPEED_M_S,
                "median_bat": asdict(self.reference),
                "definition": (
                    "mean over the bats (own length and MOI) of e_A from predict_bat (pivoted bat with"
                    " hoop mode), metrics by compute_metrics"
                ),
            },
            "trend": self.trend,
            "calibrated_model": self.calibrated,
        }


def _trend(
    bats: Sequence[PopulationBat], name: str, model: dict[str, list[float]]
) -> dict[str, float | None]:
    pairs = [(b.hoop_hz, b.metric(name)) for b in bats if b.metric(name) is not None]
    out: dict[str, float | None] = {"n": float(len(pairs)), "slope_per_khz": None, "r": None}
    if len(pairs) >= 3:
        h = np.array([p[0] for p in pairs]) / 1000.0
        v = np.array([p[1] for p in pairs], dtype=float)
        if np.ptp(h) > 0:
            out["slope_per_khz"] = float(np.polyfit(h, v, 1)[0])
            out["r"] = float(np.corrcoef(h, v)[0, 1]) if np.ptp(v) > 0 else None
    mh = np.array(model["hoop_hz"]) / 1000.0
    mv = np.array(model[name])
    if pairs:
        lo, hi = min(p[0] for p in pairs) / 1000.0, max(p[0] for p in pairs) / 1000.0
        sel = (mh >= lo) & (mh <= hi)
        if sel.sum() >= 2:
            out["model_slope_per_khz"] = float(np.polyfit(mh[sel], mv[sel], 1)[0])
    return out


def calibrated_curves(
    bats: Sequence[PopulationBat], hoop_hz: HoopGrid, cal: CalibrationFile, source: str = ""
) -> dict[str, Any]:
    """The calibrated model over the grid: the calibration's parameters (calibrate.model_params).

    Like the paper's curve, the mean over the bats' own length and MOI, but struck where the
    calibration puts each bat: its own location_in, else the calibration's default location. The
    offset of an offset variant is in the calibration's metric and is added to that metric only.
    """
    from rig.population.calfile import calibration_base
    from rig.population.calibrate import model_params

    params = model_params(cal.parameters, calibration_base(cal))
    curves: dict[str, Any] = population_curves(
        bats, hoop_hz, cal.speed_m_s, params, location_in=cal.default_location_in
    )
    offset = cal.parameters.get("offset", 0.0)
    curves[cal.metric] = [v + offset for v in curves[cal.metric]]
    return {
        **curves,
        "file": source,
        "metric": cal.metric,
        "variant": cal.variant,
        "parameters": dict(cal.parameters),
        "loo_rmse": cal.loo_rmse,
        "provenance": cal.provenance.model_dump(),
        "definition": (
            "mean over the bats (own length, MOI and location_in, else the calibration's default"
            f" {cal.default_location_in:g} in) of e_A from predict_bat with the calibrated parameters;"
            + (f" offset {offset:+.4g} added to {cal.metric} only" if offset else "")
        ),
    }


def run_study(
    bats: Sequence[PopulationBat],
    sources: Sequence[str] = (),
    notes: Sequence[str] = (),
    calibration: CalibrationFile | None = None,
    calibration_source: str = "",
) -> PopulationStudy:
    """Bin the metrics, compute the model curve (and the calibrated one, if given) and the trends."""
    bats = tuple(sorted(bats, key=lambda b: b.hoop_hz))
    hoops = [b.hoop_hz for b in bats]
    bins = {
        name: bin_by_hoop(hoops, [b.metric(name) for b in bats], BIN_WIDTH_HZ, HALF_WIDTH_HZ)
        for name in METRICS
    }
    reference = ReferenceBat.of(bats)
    model = population_curves(bats, grid_for(hoops)) if bats else {"hoop_hz": [], **{m: [] for m in METRICS}}
    trend = {name: _trend(bats, name, model) for name in METRICS} if bats else {}
    calibrated = None
    if calibration is not None and bats:
        calibrated = calibrated_curves(bats, grid_for(hoops), calibration, calibration_source)
        for name in METRICS:
            cal_trend = _trend(bats, name, calibrated)
            if "model_slope_per_khz" in cal_trend:
                trend[name]["calibrated_slope_per_khz"] = cal_trend["model_slope_per_khz"]
    return PopulationStudy(bats, bins, model, reference, trend, tuple(sources), tuple(notes), calibrated)
