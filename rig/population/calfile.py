"""The calibration file: the chosen variant's parameters and covariance, and where they came from.

JSON, written by `rig model calibrate` and read back with `load_calibration` (validated: unknown
keys, a covariance of the wrong shape or a non-finite value are refused with the file named).
"""

from __future__ import annotations

import hashlib
import json
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError, model_validator

from rig.core.errors import ConfigError, ParameterError
from rig.core.files import DATA_BYTES, read_json_file
from rig.core.version import __version__
from rig.measure.registry import cross_checked
from rig.measure.selection import variant_rows
from rig.physics import CollisionParams
from rig.population.calcheck import check_calibration
from rig.population.calibrate import (
    DEFAULT_LOCATION_IN,
    PAPER_BASE,
    UNITS,
    VARIANTS,
    Calibration,
    FitBat,
    fitted_quantity,
    model_params,
    predict,
)

KIND = "rig-model-calibration"
FORMAT = 1
SELECTION = (
    "leave-one-out prediction error; the simplest variant whose mean squared LOO error lies within one"
    " standard error of the best one's"
)


def _cross_checked(name: str) -> str:
    if name not in cross_checked():
        raise ValueError(
            f"the model cross-check does not support {name!r}; it supports {', '.join(cross_checked())}"
        )
    return name


class Provenance(BaseModel):
    """Where the calibration came from."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    data_file: str
    data_sha256: str
    n_bats: int
    hoop_min_hz: float
    hoop_max_hz: float
    created_utc: str
    software: str
    moi_min_kgm2: float | None = None  # the bats' MOI range (None: a file from before it was kept)
    moi_max_kgm2: float | None = None

    def covers(self, hoop_hz: float, moi_kgm2: float) -> bool:
        """Whether a bat lies inside the calibrated hoop-frequency (and, where kept, MOI) range."""
        if not self.hoop_min_hz <= hoop_hz <= self.hoop_max_hz:
            return False
        if self.moi_min_kgm2 is None or self.moi_max_kgm2 is None:
            return True
        return self.moi_min_kgm2 <= moi_kgm2 <= self.moi_max_kgm2

    def range_text(self) -> str:
        """The calibrated range in words: 'hoop 1400-3000 Hz, MOI 0.170-0.215 kg m²'."""
        text = f"hoop {self.hoop_min_hz:.0f}-{self.hoop_max_hz:.0f} Hz"
        if self.moi_min_kgm2 is not None and self.moi_max_kgm2 is not None:
            text += f", MOI {self.moi_min_kgm2:.3f}-{self.moi_max_kgm2:.3f} kg m²"
        return text


class CalibrationFile(BaseModel):
    """The file's contents (the chosen variant; every variant's scores under `variants`)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    kind: Literal["rig-model-calibration"]
    format: Literal[1]
    metric: Annotated[str, AfterValidator(_cross_checked)]  # a metric the registry lets it support
    speed_m_s: float
    default_location_in: float
    variant: str
    parameters: dict[str, float]
    uncertainty: dict[str, float]
    units: dict[str, str]
    covariance: list[list[float]]
    scatter: float
    loo_rmse: float
    model_params: CollisionParams
    selection: str
    variants: list[dict[str, Any]]
    bats: list[dict[str, Any]]
    notes: list[str] = []
    provenance: Provenance
    # the fitted ball the calibration solved with (file name, sha256, lot, variant, constants);
    # None: the paper's ball
    ball: dict[str, Any] | None = None
    # what the bats' measured values are when not the metric: "bbcor" for a BPF or a USA Softball
    # BBS (rig.population.calibrate.fitted_quantity); None: the metric itself
    fitted: Literal["bbcor"] | None = None

    @property
    def fitted_metric(self) -> str:
        """The quantity the calibration fitted (its bats' measured values, its scatter's unit)."""
        return self.fitted or self.metric

    @model_validator(mode="before")
    @classmethod
    def _in_variant_order(cls, data: Any) -> Any:
        """parameters and uncertainty in the variant's order, the covariance's (a store sorts keys)."""
        if not isinstance(data, dict) or data.get("variant") not in VARIANTS:
            return data
        names = VARIANTS[data["variant"]]
        out = dict(data)
        for key in ("parameters", "uncertainty"):
            value = data.get(key)
            if isinstance(value, dict) and set(value) == set(names):
                out[key] = {n: value[n] for n in names}
        return out

    @model_validator(mode="after")
    def _shapes(self) -> CalibrationFile:
        names = VARIANTS.get(self.variant)
        if names is None:
            raise ValueError(f"unknown variant {self.variant!r}; known: {', '.join(VARIANTS)}")
        if tuple(self.parameters) != names:
            raise ValueError(f"variant {self.variant} has parameters {', '.join(names)}")
        if len(self.covariance) != len(names) or any(len(r) != len(names) for r in self.covariance):
            raise ValueError(f"covariance must be {len(names)} x {len(names)}")
        if self.fitted is not None and self.fitted != fitted_quantity(self.metric):
            raise ValueError(
                f"a {self.metric} calibration fits {fitted_quantity(self.metric)}, not {self.fitted}"
            )
        check_calibration(self)  # physical ranges, a covariance that is one (ParameterError)
        return self


def calibration_base(cal: CalibrationFile) -> CollisionParams:
    """The ball's constants a calibration was made with: its recorded ball's, else the paper's."""
    if cal.ball is None:  # the paper's ball at the mass of the runs' balls
        return PAPER_BASE.model_copy(update={"m1": cal.model_params.m1})
    return PAPER_BASE.model_copy(update=dict(cal.ball["constants"]))


def calibration_record(
    cal: Calibration, data: bytes, data_file: str, ball: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The JSON record of a calibration, with the data's hash, the software's version and the
    fitted ball it was made with (`ball`: rig.physics.ball_law.ball_record; None: the paper's)."""
    fit = cal.fit
    predicted = predict(cal.bats, fit.values, base=cal.base)
    loo = cal.reports[cal.chosen].loo_errors
    hoops = [b.hoop_hz for b in cal.bats]
    mois = [b.pivoted.moi_kgm2 for b in cal.bats]
    variants = variant_rows(cal.reports)
    return {
        "kind": KIND,
        "format": FORMAT,
        "metric": cal.metric,
        "speed_m_s": cal.speed_m_s,
        **({} if cal.fitted == cal.metric else {"fitted": cal.fitted}),
        "default_location_in": DEFAULT_LOCATION_IN,
        "variant": cal.chosen,
        "parameters": fit.values,
        "uncertainty": fit.errors(),
        "units": {n: UNITS[n] for n in fit.names},
        "covariance": fit.covariance.tolist(),
        "scatter": fit.scatter,
        "loo_rmse": cal.reports[cal.chosen].loo_rmse,
        "model_params": model_params(fit.values, cal.base).model_dump(),
        "selection": SELECTION,
        "variants": variants,
        "bats": [
            {
                "bat_id": b.bat_id,
                "hoop_hz": b.hoop_hz,
                "measured": b.measured,
                "predicted": float(p),
                "residual": b.measured - float(p),
                "loo_error": float(e),
                **bat_geometry(b),
            }
            for b, p, e in zip(cal.bats, predicted, loo, strict=True)
        ],
        "notes": list(cal.notes),
        "provenance": {
            "data_file": data_file,
            "data_sha256": hashlib.sha256(data).hexdigest(),
            "n_bats": len(cal.bats),
            "hoop_min_hz": min(hoops),
            "hoop_max_hz": max(hoops),
            "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
            "software": f"rig {__version__}",
            "moi_min_kgm2": min(mois),
            "moi_max_kgm2": max(mois),
        },
        "ball": ball,
    }


def bat_geometry(bat: FitBat) -> dict[str, float]:
    """What a screen needs of a calibrated bat besides its hoop frequency (rig.population.screen):
    its MOI about the pivot and, where known, its length and impact location."""
    out = {"moi_kgm2": bat.pivoted.moi_kgm2}
    if math.isfinite(bat.length_in) and math.isfinite(bat.location_in):
        out |= {"length_in": bat.length_in, "location_in": bat.location_in}
    return out


def write_calibration(record: dict[str, Any], path: str | Path) -> Path:
    """Write the record as JSON (validated first, so that what is written can be read back)."""
    parse_calibration(record, str(path))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path


def load_calibration(path: str | Path) -> CalibrationFile:
    """Read and validate a calibration file; ConfigError names the file and the first problem."""
    return read_calibration(path)[0]


def read_calibration(path: str | Path) -> tuple[CalibrationFile, bytes]:
    """The validated calibration and the bytes it was read from (what a run records and hashes)."""
    data, raw = read_json_file(path, DATA_BYTES, "a calibration file")
    return parse_calibration(data, str(path)), raw


def parse_calibration(data: Any, source: str) -> CalibrationFile:
    """Validate a calibration's parsed JSON; ConfigError names `source` and the first bad field."""
    try:
        return CalibrationFile.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        cause = first.get("ctx", {}).get("error")
        if isinstance(cause, ParameterError):  # check_calibration's: it names the field itself
            raise ConfigError(str(cause), source=source) from None
        field = ".".join(str(p) for p in first["loc"]) or "file"
        raise ConfigError(first["msg"], source=source, field=field) from None


def covariance_matrix(cal: CalibrationFile) -> np.ndarray:
    """The chosen variant's parameter covariance as an array."""
    return np.array(cal.covariance, dtype=float)
