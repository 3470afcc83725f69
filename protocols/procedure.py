"""A certification procedure as data: what to measure, how often, and the limits (TOML).

Values that docs/standards.md marks unknown are configurable defaults, each commented in the
built-in files (protocols/*.toml) with its status.
"""

from __future__ import annotations

from datetime import date
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    ValidationInfo,
    field_validator,
    model_validator,
)

from rig.core.errors import ConfigError
from rig.core.tomlfile import read_toml, table, validate
from rig.measure.registry import BUILTIN_PROCEDURES, Metric, metric, resolve

BUILTIN_DIR = Path(__file__).parent
BUILTIN = tuple(name for _, name in BUILTIN_PROCEDURES)  # each is protocols/<name>.toml
M = TypeVar("M", bound=BaseModel)


def load_table(cls: type[M], name_or_path: str | Path, builtin: tuple[str, ...], what: str) -> tuple[M, Path]:
    """Table [procedure] of a built-in file by name (one of `builtin`) or of a TOML file, validated as
    `cls`; errors name the file and the field. Also returns the file's path."""
    path = Path(name_or_path)
    if str(name_or_path) in builtin:
        path = BUILTIN_DIR / f"{name_or_path}.toml"
    missing = f"no such {what}; built-in ones are {', '.join(builtin)}"
    data = read_toml(path, missing=missing, what=f"a {what} file")
    return validate(cls, table(data, "procedure", str(path)), str(path), prefix="procedure."), path


def _registered(name: str) -> str:
    try:
        return metric(name).name
    except ConfigError as exc:
        raise ValueError(exc.reason) from None


MetricName = Annotated[str, AfterValidator(_registered)]  # a metric of rig.measure.registry


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class Scan(_Model):
    """Impact-location scan, distances from the barrel end (inches)."""

    # On the bat: at most 36 in from the tip (a 42 in bat's pivot); steps of 0.1-10 in (a ball's
    # contact patch is about an inch across, so finer steps resolve nothing).
    from_in: Annotated[float, Field(gt=0.0, le=36.0)] = 5.0
    to_in: Annotated[float, Field(gt=0.0, le=36.0)] = 7.5
    step_in: Annotated[float, Field(ge=0.1, le=10.0)] = 0.5
    hits_per_location: Annotated[int, Field(ge=1, le=10)] = 1
    # how far beyond either end the runner may extend the scan to bracket the maximum (inches)
    extend_in: Annotated[float, Field(ge=0.0, le=10.0)] = 1.0

    @model_validator(mode="after")
    def _order(self) -> Scan:
        if self.to_in < self.from_in:
            raise ValueError("scan.to_in must not be less than scan.from_in")
        if self.count > 40:
            raise ValueError(f"scan has {self.count} locations; at most 40")
        return self

    @property
    def count(self) -> int:
        """Number of locations."""
        return round((self.to_in - self.from_in) / self.step_in) + 1

    def locations_in(self) -> list[float]:
        """The scan's locations from the barrel end, inches."""
        return [round(self.from_in + i * self.step_in, 6) for i in range(self.count)]


class Hits(_Model):
    """The valid hits that make the bat's result."""

    valid_hits: Annotated[int, Field(ge=1, le=50)] = 6
    max_reshoots: Annotated[int, Field(ge=0, le=100)] = 10  # invalid shots allowed in the whole run


class Ball(_Model):
    """Ball handling, and the rules for the balls of a named lot (`rig certify --ball-lot`)."""

    mass_kg: Annotated[float, Field(gt=0.1, lt=0.2)] = 0.145
    replace_after_hits: Annotated[int, Field(ge=1, le=1000)] = 12
    # a named lot must state at least this many days of conditioning (None: no rule)
    conditioning_days_min: Annotated[float, Field(ge=0.0, le=3650.0)] | None = None
    # at each shot, the lab's air within this of the lot's conditioning temperature / humidity
    air_window_c: Annotated[float, Field(gt=0.0, le=30.0)] | None = None
    air_window_pct: Annotated[float, Field(gt=0.0, le=100.0)] | None = None
    # a softball's class, COR/compression (lbf): "44/375" is COR .44, 375 lbf (ASTM F1887, F1888)
    ball_class: Annotated[str, Field(pattern=r"^\.?[0-9]{2}/[0-9]{3}$")] | None = None


class EnvironmentLimits(_Model):
    """Lab conditions that must hold before firing: (low, high), low below high."""

    # a lab's air: -10 to 50 C (the ENV sensor's range), 0-100 % relative humidity
    temperature_c: tuple[
        Annotated[float, Field(ge=-10.0, le=50.0)], Annotated[float, Field(ge=-10.0, le=50.0)]
    ] = (18.0, 26.0)
    humidity_pct: tuple[
        Annotated[float, Field(ge=0.0, le=100.0)], Annotated[float, Field(ge=0.0, le=100.0)]
    ] = (
        30.0,
        70.0,
    )

    @model_validator(mode="after")
    def _low_first(self) -> EnvironmentLimits:
        for name in ("temperature_c", "humidity_pct"):
            low, high = getattr(self, name)
            if not low < high:
                raise ValueError(f"{name} is (low, high): {low:g} must be below {high:g}")
        return self


class Moi(_Model):
    """Where the bat's MOI about the pivot comes from; its u is derived (rig.measure.moi)."""

    source: Literal["pendulum", "entered"] = "pendulum"
    cycles: Annotated[int, Field(ge=1, le=100)] = 10
    repeats: Annotated[int, Field(ge=1, le=20)] = 3  # timings of `cycles` periods; their scatter is a u
    # Deprecated, ignored: the MOI's u was a fixed fraction before it was derived from the
    # pendulum's inputs. Kept so that procedures recorded in older runs still load.
    relative_uncertainty: Annotated[float, Field(gt=0.0, lt=0.1)] | None = Field(
        None, deprecated=True, exclude=True
    )


class Decision(_Model):
    """Decision rule: guarded acceptance, pass only if mean + guard <= limit."""

    rule: Literal["guarded", "simple"] = "guarded"
    coverage_k: Annotated[float, Field(gt=0.0, le=3.0)] = 2.0


class Procedure(_Model):
    """A certification procedure, pinned to the edition it follows."""

    name: str
    standard: MetricName  # which metric decides the verdict
    edition: str
    # the date the followed edition took force; a dated standard (usas_bbs) chooses its edition by it
    edition_date: date | None = None
    limit: float  # bounded by the metric in _limit_fits_metric
    # the bat's constraint its BBCOR assumes, where the file states it: the metric's must be it
    # (rig.measure.bpf: ASTM F1890-23 pivoted, F2219-23 unconstrained)
    basis: Literal["pivoted", "unconstrained"] | None = None
    limit_note: str = ""
    target_speed_m_s: Annotated[float, Field(gt=10.0, lt=80.0)] = 60.8
    speed_tolerance_m_s: Annotated[float, Field(gt=0.0, lt=10.0)] = 0.447  # 1 mph
    scan: Scan = Scan()
    hits: Hits = Hits()
    ball: Ball = Ball()
    environment: EnvironmentLimits = EnvironmentLimits()
    moi: Moi = Moi()
    ring_check: StrictBool = True  # true or false; "yes" is refused
    decision: Decision = Decision()
    # kept so that old records' procedures still validate; the calibrated interval replaced it
    cross_check_tolerance: Annotated[float, Field(gt=0.0, le=10.0)] = 0.05
    # the model calibration (rig model calibrate) the cross-check uses; relative to this file
    calibration: Annotated[str, Field(min_length=1, max_length=4096)] | None = None
    cross_check_coverage: Annotated[float, Field(gt=0.5, lt=1.0)] = 0.95  # of the prediction interval

    @model_validator(mode="before")
    @classmethod
    def _choose_edition(cls, data: Any) -> Any:
        # a dated family names one edition's metric by the edition date; that edition's cannon
        # speed is the target unless the file gives one (checked against it in _speed_fits_metric)
        if not isinstance(data, dict) or not isinstance(data.get("standard"), str):
            return data
        on = data.get("edition_date")
        try:
            name = resolve(data["standard"], on if isinstance(on, date) else None)
        except ConfigError as exc:
            raise ValueError(exc.reason) from None
        if name == data["standard"]:
            return data
        chosen = {**data, "standard": name}
        speed = metric(name).test_speed_m_s
        if speed is not None and "target_speed_m_s" not in data:
            chosen["target_speed_m_s"] = round(speed, 4)
        return chosen

    @model_validator(mode="after")
    def _speed_fits_metric(self) -> Procedure:
        speed = self.metric.test_speed_m_s
        if speed is not None and abs(self.target_speed_m_s - speed) > self.speed_tolerance_m_s:
            raise ValueError(
                f"target_speed_m_s {self.target_speed_m_s:g} is not the {self.standard} test speed "
                f"{speed:.4g} m/s (within the speed tolerance)"
            )
        return self

    @model_validator(mode="after")
    def _basis_fits_metric(self) -> Procedure:
        own = self.metric.basis.split(" ", 1)[0].rstrip(":")
        if self.basis is not None and own != self.basis:
            said = f"the {own} one" if own else "none stated"
            raise ValueError(f"basis {self.basis!r}: the {self.standard} metric's basis is {said}")
        return self

    @field_validator("limit")
    @classmethod
    def _limit_fits_metric(cls, v: float, info: ValidationInfo) -> float:
        # each metric's range is its registry entry's (BBCOR a COR, (0, 1]; BBS in m/s, (0, 100])
        standard = info.data.get("standard")
        if standard is None:
            return v
        low, high = metric(standard).limit_range
        if not low < v <= high:
            raise ValueError(f"{v:g} is outside ({low:g}, {high:g}] for {standard}")
        return v

    @property
    def metric(self) -> Metric:
        """The registry's entry for the metric the procedure certifies."""
        return metric(self.standard)

    @classmethod
    def load(cls, name_or_path: str | Path) -> Procedure:
        """A built-in procedure by name (bbcor, besr, bbs) or a TOML file; errors name the field."""
        proc, path = load_table(cls, name_or_path, BUILTIN, "procedure")
        if proc.calibration is not None:  # a relative path is relative to the procedure file
            proc = proc.model_copy(
                update={"calibration": str(path.parent / Path(proc.calibration).expanduser())}
            )
        return proc
