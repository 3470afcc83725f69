"""The bat under test, as its TOML file describes it (table [bat])."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from rig.core.tomlfile import read_toml, table, validate
from rig.core.units import INCH, OUNCE

PIVOT_FROM_KNOB_IN = 6.0  # NCAA/ASTM F2398 pivot point
PIVOT_FROM_KNOB_M = PIVOT_FROM_KNOB_IN * INCH


class Barrel(StrEnum):
    """Barrel material."""

    ALUMINIUM = "aluminium"
    COMPOSITE = "composite"
    WOOD = "wood"


class BatSpec(BaseModel):
    """Identity and properties of a bat; optional values are measured or left to the model."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    id: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9._-]+$")]
    length_in: Annotated[float, Field(gt=20.0, lt=40.0)]
    weight_oz: Annotated[float, Field(gt=10.0, lt=50.0)]
    barrel: Barrel
    hoop_hz: Annotated[float, Field(gt=0.0)] | None = None
    moi_kgm2: Annotated[float, Field(gt=0.0, lt=1.0)] | None = None  # about the pivot 6 in from the knob
    moi_u_kgm2: Annotated[float, Field(gt=0.0, lt=0.1)] | None = None  # standard u of an entered moi_kgm2
    balance_point_in: Annotated[float, Field(gt=0.0, lt=40.0)] | None = None  # from the knob end

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
        data = read_toml(path)
        return validate(cls, table(data, "bat", str(path)), str(path), prefix="bat.")
