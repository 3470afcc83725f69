"""The bat under test, as its TOML file describes it (table [bat])."""

from __future__ import annotations

from datetime import date
from enum import StrEnum
from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationInfo, field_validator

from rig.core.lab import Line, Lines
from rig.core.tomlfile import read_toml, table, validate
from rig.core.units import INCH, OUNCE

PIVOT_FROM_KNOB_IN = 6.0  # NCAA/ASTM F2398 pivot point
PIVOT_FROM_KNOB_M = PIVOT_FROM_KNOB_IN * INCH

# Physical bounds of a bat (docs/procedures.md, "Bounds"). Length: youth bats start near 24 in and
# the longest legal bat is 42 in (MLB rule 3.02). Weight: 10-50 oz spans tee-ball to fungo bats.
# Hoop frequency: hollow barrels ring at about 1-4 kHz; 200-10000 Hz leaves room either side while
# the model still returns a ball (below ~10 Hz the barrel swallows it: v_out < 0). MOI about the
# pivot: a 20 in, 10 oz bat has about 0.01 kg m^2, a 42 in, 50 oz bat about 0.6; 1 kg m^2 is no bat.
LENGTH_IN = (20.0, 42.0)
WEIGHT_OZ = (10.0, 50.0)
HOOP_HZ = (200.0, 10000.0)
MOI_KGM2 = (0.01, 1.0)


class Barrel(StrEnum):
    """Barrel material."""

    ALUMINIUM = "aluminium"
    COMPOSITE = "composite"
    WOOD = "wood"


class SimulatedTruth(BaseModel):
    """A bat file's [simulated] table: the simulated bat's true properties where they differ from,
    or are missing in, its [bat] table. Only the simulated rig reads them (rig.session); the
    controller never does, and they are not part of the bat's record."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    moi_kgm2: Annotated[float, Field(ge=MOI_KGM2[0], le=MOI_KGM2[1])] | None = None
    hoop_hz: Annotated[float, Field(ge=HOOP_HZ[0], le=HOOP_HZ[1])] | None = None
    alteration_bbcor: Annotated[float, Field(ge=0.0, le=0.1)] = 0.0


SUBMISSION = ("customer", "maker", "model", "serial", "condition", "received")


class BatSpec(BaseModel):
    """Identity and properties of a bat; optional values are measured or left to the model."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    id: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9._-]+$")]
    length_in: Annotated[float, Field(ge=LENGTH_IN[0], le=LENGTH_IN[1], description="20-42 in")]
    weight_oz: Annotated[float, Field(ge=WEIGHT_OZ[0], le=WEIGHT_OZ[1], description="10-50 oz")]
    barrel: Barrel
    hoop_hz: Annotated[float, Field(ge=HOOP_HZ[0], le=HOOP_HZ[1], description="200-10000 Hz")] | None = None
    # about the pivot 6 in from the knob
    moi_kgm2: Annotated[float, Field(ge=MOI_KGM2[0], le=MOI_KGM2[1])] | None = None
    moi_u_kgm2: Annotated[float, Field(gt=0.0, lt=0.1)] | None = None  # standard u of an entered moi_kgm2
    # from the knob end, on the bat past the pivot
    balance_point_in: Annotated[float, Field(gt=PIVOT_FROM_KNOB_IN, lt=LENGTH_IN[1])] | None = None
    # The item as the test report describes it (ISO/IEC 17025 7.8.2.1): optional, and not part of the
    # bat's registration (SUBMISSION), so that bat files written before them stay valid and the same.
    customer: Lines | None = None  # who submitted the bat (name, and address if wanted)
    maker: Line | None = None
    model: Line | None = None
    serial: Line | None = None
    condition: Lines | None = None  # the bat's condition on receipt, e.g. "new, no visible damage"
    received: date | None = None  # date of receipt at the lab
    _simulated: SimulatedTruth | None = PrivateAttr(default=None)

    def __eq__(self, other: object) -> bool:
        """Equal bat properties (the simulated truth, which is not the bat's record, aside)."""
        if not isinstance(other, BatSpec):
            return NotImplemented
        return self.model_dump() == other.model_dump()

    def __hash__(self) -> int:
        return hash(tuple(self.model_dump().items()))

    def registered(self) -> dict[str, object]:
        """What the store registers of the bat: its properties, without the submission's details."""
        return self.model_dump(mode="json", exclude=set(SUBMISSION))

    @property
    def simulated(self) -> SimulatedTruth | None:
        """The file's [simulated] table (the simulated bat's true properties), if it has one."""
        return self._simulated

    @field_validator("balance_point_in")
    @classmethod
    def _on_the_bat(cls, v: float | None, info: ValidationInfo) -> float | None:
        # On the bat beyond the pivot; and the parallel-axis theorem puts the MOI about the pivot
        # at no less than m d^2 (d: pivot to balance point).
        length, weight, moi = (info.data.get(k) for k in ("length_in", "weight_oz", "moi_kgm2"))
        if v is None or length is None or weight is None:
            return v
        if not v < length:
            raise ValueError(f"{v:g} in must lie on the bat, before its tip at {length:g} in")
        m_d2 = weight * OUNCE * (v * INCH - PIVOT_FROM_KNOB_M) ** 2
        if moi is not None and moi < m_d2:
            raise ValueError(
                f"with moi_kgm2 = {moi:g} it needs MOI >= m d^2 = {m_d2:.4f} kg m^2: "
                "no bat has a negative MOI about its centre of mass"
            )
        return v

    @property
    def length_m(self) -> float:
        """Overall length, m."""
        return self.length_in * INCH

    @property
    def mass_kg(self) -> float:
        """Mass, kg."""
        return self.weight_oz * OUNCE

    @property
    def drop(self) -> float:
        """Weight (oz) minus length (in), the "drop": at least -3 for NCAA/NFHS bats."""
        return self.weight_oz - self.length_in

    def impact_from_pivot_m(self, from_barrel_end_in: float) -> float:
        """Pivot-to-impact distance Q for an impact `from_barrel_end_in` inches from the tip."""
        return self.length_m - PIVOT_FROM_KNOB_M - from_barrel_end_in * INCH

    @classmethod
    def load(cls, path: str | Path) -> BatSpec:
        """Read table [bat] of a TOML file; errors name the file and the field."""
        data = read_toml(path, what="a bat file")
        bat = validate(cls, table(data, "bat", str(path)), str(path), prefix="bat.")
        if "simulated" in data:
            bat._simulated = validate(
                SimulatedTruth, table(data, "simulated", str(path)), str(path), "simulated."
            )
        return bat
