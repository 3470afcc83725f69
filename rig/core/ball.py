"""Ball lots and their measured results: what `rig balls register` reads and the store keeps.

A `BallLot` is the register file's table [lot]: the lot's identity, the specification values the
lab enters (each optional) and how its balls were conditioned. A `LotResult` is one measurement of
the lot by a ball test on the rig (`ccor` against the rigid cylinder, `ball-cor` against the rigid
plate): it is derived from the test run's recorded shots, and kept in that run's RunFinished.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from rig.core.tomlfile import read_toml, table, validate

BALL_TESTS = ("ccor", "ball-cor")
LOT_ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,39}$"
Cor = Annotated[float, Field(gt=0.0, lt=1.0)]


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class BallSpecification(_Model):
    """The maker's or the rule's values for the lot, as the lab enters them (each optional)."""

    nominal_cor: Cor | None = None  # flat wall at 60 mph (ASTM F1887)
    cor_tolerance: Annotated[float, Field(gt=0.0, lt=0.5)] | None = None  # +- about nominal_cor
    nominal_ccor: Cor | None = None  # on a cylinder (the founding paper; ASTM F2845)
    compression_lbf: Annotated[float, Field(gt=0.0, le=2000.0)] | None = None  # ASTM F1888, 0.25 in
    mass_kg: Annotated[float, Field(ge=0.05, le=0.5)] | None = None  # baseball 0.142-0.149 kg


class Conditioning(_Model):
    """How the lot was conditioned before its tests (a lab's rule, e.g. 50 % RH for two weeks)."""

    temperature_c: Annotated[float, Field(ge=-10.0, le=50.0)] | None = None
    humidity_pct: Annotated[float, Field(ge=0.0, le=100.0)] | None = None
    days: Annotated[float, Field(ge=0.0, le=3650.0)] | None = None


class BallLot(_Model):
    """A lot of balls: one maker, one model, conditioned together (table [lot] of LOT.toml)."""

    id: Annotated[str, Field(pattern=LOT_ID_PATTERN)]
    maker: Annotated[str, Field(min_length=1, max_length=100)]
    model: Annotated[str, Field(min_length=1, max_length=100)]
    balls: Annotated[int, Field(ge=1, le=999)] = 24  # balls in the lot; ball ids LOT-01, LOT-02, ...
    specification: BallSpecification = BallSpecification()
    conditioning: Conditioning = Conditioning()
    note: Annotated[str, Field(max_length=2000)] = ""

    def meets(self, quantity: str, mean: float, big_u: float) -> bool | None:
        """Whether a measured COR (CCOR) with its U can meet the lot's specification: False only if
        |mean - nominal| > tolerance + U; None where the lot states no nominal value with a tolerance."""
        spec = self.specification
        nominal = spec.nominal_ccor if quantity == "ccor" else spec.nominal_cor
        tolerance = spec.cor_tolerance if quantity == "cor" else None
        if nominal is None or tolerance is None:
            return None
        return abs(mean - nominal) <= tolerance + big_u

    def ball_id(self, number: int) -> str:
        """The id of ball `number` (1-based) of this lot: LOT-01, LOT-02, ... (LOT-001 past 99)."""
        width = 2 if self.balls < 100 else 3
        return f"{self.id}-{number:0{width}d}"

    @classmethod
    def load(cls, path: str | Path) -> BallLot:
        """Read table [lot] of a TOML file; errors name the file and the field."""
        data = read_toml(path, what="a lot file")
        return validate(cls, table(data, "lot", str(path)), str(path), prefix="lot.")


class CcorPoint(_Model):
    """One valid hit of a ball test: the speed at the impact point and the COR (CCOR) it gave."""

    speed_m_s: float  # measured inbound speed at the impact point, drag corrected
    target_speed_m_s: float
    cor: float  # rebound / inbound speed at the impact point
    u: float  # this hit's standard uncertainty (its own GUM budget)
    ball_id: str
    ball_hit: int  # the ball's hit count at this hit (1: its first impact)
    shot: int  # the shot's index in the run
    temp_c: float | None = None  # the lab's air at the shot (older records: None)
    rh_pct: float | None = None


class SpeedPoint(_Model):
    """The lot's mean COR (CCOR) at one nominal speed."""

    target_speed_m_s: float
    speed_m_s: float  # mean measured speed at the impact point
    mean: float
    u: float
    sd: float | None  # over the hits at this speed
    n: int


class LotResult(_Model):
    """One measured result of a lot (a finished ball test), derived from its run's shots."""

    lot_id: str
    procedure: Literal["ccor", "ball-cor"]
    quantity: Literal["ccor", "cor"]
    target: dict[str, float | str | None]  # {"kind": "cylinder"|"plate", "diameter_m": ...}
    speeds_m_s: tuple[float, ...]  # the nominal inbound speeds
    mean: float  # ball-cor: the lot's COR; ccor: the mean CCOR over every hit (see per_speed)
    u: float
    U: float
    coverage_k: float
    sd_between_balls: float | None  # spread of the balls' own means, the within-ball scatter removed
    wear_per_hit: float | None  # slope of COR against the ball's hit count (within each ball)
    wear_per_hit_u: float | None
    speed_slope: float | None = None  # COR per m/s of inbound speed within balls (a regressor of the wear)
    speed_slope_u: float | None = None
    mean_hit: float  # the mean hit count of the hits behind `mean`
    n_balls: int
    hits_per_ball: int
    n_hits: int
    temp_c: float | None
    rh_pct: float | None
    run_id: str
    per_ball: dict[str, float] = {}  # ball id -> its mean COR (CCOR)
    per_speed: tuple[SpeedPoint, ...] = ()
    points: tuple[CcorPoint, ...] = ()
