"""A bat population for the study of the founding paper's section 5: its CSV and TOML formats.

One bat per row (CSV) or per [[bat]] table (TOML), keys as in COLUMNS:
  bat_id      identifier (letters, digits, '.', '_', '-')
  barrel      aluminium | composite | wood
  hoop_hz     first hoop frequency, Hz (required)
  bending_hz  first bending frequency, Hz (optional)
  length_in, weight_oz, moi_kgm2 (about the pivot 6 in from the knob)   optional
  location_in impact location of the measured metric, in from the barrel end (optional; where the
              certification found its maximum)
  besr, bbs (m/s), bbcor   measured performance, each optional
  u_besr, u_bbs, u_bbcor   their standard uncertainties (k = 1), each optional
  source      where the row comes from (free text; "synthetic ..." marks made-up data)
CSV: comment lines start with '#'; the header names the columns (any order, these names only);
an empty cell is a missing value. TOML: the same keys; a missing key is a missing value.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.core.bat import HOOP_HZ, LENGTH_IN, MOI_KGM2, WEIGHT_OZ, Barrel
from rig.core.errors import ConfigError, listed, shown
from rig.core.files import DATA_BYTES, parse_toml, read_bounded

WHAT = "a population file"
COLUMNS = (
    "bat_id",
    "barrel",
    "hoop_hz",
    "bending_hz",
    "length_in",
    "weight_oz",
    "moi_kgm2",
    "location_in",
    "besr",
    "bbs",
    "bbcor",
    "u_besr",
    "u_bbs",
    "u_bbcor",
    "source",
)
METRICS = ("besr", "bbs", "bbcor")  # a column for each metric the registry lets the cross-check support
U_COLUMNS = ("u_besr", "u_bbs", "u_bbcor")


def missing_column(bats: Sequence[PopulationBat], columns: Sequence[str]) -> str | None:
    """'missing column C: no value for k of n bats (first ID)' for the first column lacking, else None."""
    for column in columns:
        lacking = [b.bat_id for b in bats if getattr(b, column) is None]
        if lacking:
            n = f"{len(lacking)} of {len(bats)}"
            return f"missing column {column}: no value for {n} bats (first {lacking[0]})"
    return None


def _column(name: str) -> str:
    if name not in METRICS:
        raise KeyError(name)  # as the lookup it replaces
    return name


class PopulationBat(BaseModel):
    """One bat of the population."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    bat_id: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9._-]+$")]
    barrel: Barrel
    # the bat file's bounds (rig.core.bat); a first bending mode lies near 150-200 Hz, 20-5000 Hz
    # takes in any bat's
    hoop_hz: Annotated[float, Field(ge=HOOP_HZ[0], le=HOOP_HZ[1])]
    bending_hz: Annotated[float, Field(ge=20.0, le=5000.0)] | None = None
    length_in: Annotated[float, Field(ge=LENGTH_IN[0], le=LENGTH_IN[1])] | None = None
    weight_oz: Annotated[float, Field(ge=WEIGHT_OZ[0], le=WEIGHT_OZ[1])] | None = None
    moi_kgm2: Annotated[float, Field(ge=MOI_KGM2[0], le=MOI_KGM2[1])] | None = None
    # a scan location lies on the bat: (0, 36] in from the barrel end, as the procedure's bounds
    location_in: Annotated[float, Field(gt=0.0, le=36.0)] | None = None
    besr: Annotated[float, Field(gt=0.0, lt=2.0)] | None = None
    bbs: Annotated[float, Field(gt=0.0, lt=100.0)] | None = None
    bbcor: Annotated[float, Field(gt=0.0, lt=1.0)] | None = None
    # standard uncertainties (k = 1) of the measured metrics
    u_besr: Annotated[float, Field(ge=0.0, lt=1.0)] | None = None
    u_bbs: Annotated[float, Field(ge=0.0, lt=50.0)] | None = None
    u_bbcor: Annotated[float, Field(ge=0.0, lt=1.0)] | None = None
    source: str = ""

    def metric(self, name: str) -> float | None:
        """The measured value of a metric in METRICS (besr, bbs or bbcor), when given."""
        value: float | None = getattr(self, _column(name))
        return value

    def u_metric(self, name: str) -> float | None:
        """The standard uncertainty (k = 1) of a metric in METRICS, when given."""
        value: float | None = getattr(self, f"u_{_column(name)}")
        return value

    @property
    def synthetic(self) -> bool:
        """True for made-up rows (source starting 'synthetic')."""
        return self.source.lower().startswith("synthetic")


def _validate(row: dict[str, Any], path: Path, where: str) -> PopulationBat:
    try:
        return PopulationBat.model_validate(row)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(p) for p in first["loc"]) or "row"
        raise ConfigError(
            f"{first['msg']} (got {shown(first.get('input'))})", source=f"{path}: {where}", field=field
        ) from None


def _read_csv(path: Path, text: str) -> list[PopulationBat]:
    lines = [
        (n, line) for n, line in enumerate(text.splitlines(), start=1) if not line.lstrip().startswith("#")
    ]
    lines = [(n, line) for n, line in lines if line.strip()]
    if not lines:
        raise ConfigError("no header and no rows", source=str(path))
    reader = csv.reader(io.StringIO("\n".join(line for _, line in lines)))
    try:
        rows = list(reader)
    except csv.Error as exc:
        raise ConfigError(f"not a readable CSV file: {exc}", source=str(path)) from None
    header = [c.strip() for c in rows[0]]
    unknown = [c for c in header if c not in COLUMNS]
    if unknown:
        raise ConfigError(
            f"unknown column(s) {listed(unknown)}; known: {', '.join(COLUMNS)}",
            source=f"{path}: line {lines[0][0]}",
        )
    missing = [c for c in ("bat_id", "barrel", "hoop_hz") if c not in header]
    if missing:
        raise ConfigError(f"missing column(s) {', '.join(missing)}", source=f"{path}: line {lines[0][0]}")
    bats = []
    for (line_no, _), cells in zip(lines[1:], rows[1:], strict=True):
        if len(cells) != len(header):
            raise ConfigError(
                f"{len(cells)} cells, the header has {len(header)}", source=f"{path}: line {line_no}"
            )
        row = {k: v.strip() for k, v in zip(header, cells, strict=True) if v.strip() != ""}
        bats.append(_validate(row, path, f"line {line_no}"))
    return bats


def _read_toml(path: Path, text: str) -> list[PopulationBat]:
    data = parse_toml(text, str(path), WHAT)
    tables = data.get("bat")
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise ConfigError("needs [[bat]] tables", source=str(path))
    return [_validate(t, path, f"bat {i + 1}") for i, t in enumerate(tables)]


def load_population(path: str | Path) -> list[PopulationBat]:
    """Read a population file (.csv or .toml); ids must be unique."""
    return read_population(path)[0]


def read_population(path: str | Path) -> tuple[list[PopulationBat], bytes]:
    """The population file's bats and the bytes they were read from (what a calibration hashes)."""
    path = Path(path)
    raw = read_bounded(path, DATA_BYTES, WHAT)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not {WHAT}: not UTF-8 text (byte {exc.start})", source=str(path)) from None
    bats = _read_toml(path, text) if path.suffix.lower() == ".toml" else _read_csv(path, text)
    seen: set[str] = set()
    for b in bats:
        if b.bat_id in seen:
            raise ConfigError(f"bat {b.bat_id} appears twice", source=str(path))
        seen.add(b.bat_id)
    return bats, raw


def write_population_csv(
    bats: Iterable[PopulationBat], path: str | Path, comments: Iterable[str] = ()
) -> Path:
    """Write a population in the CSV format (comment lines first)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = io.StringIO()
    for c in comments:
        out.write(f"# {c}\n")
    writer = csv.writer(out, lineterminator="\n")
    rows = [b.model_dump(mode="json") for b in bats]
    # the uncertainty columns only when some bat has one: files without them stay as they were
    columns = [c for c in COLUMNS if c not in U_COLUMNS or any(d[c] is not None for d in rows)]
    writer.writerow(columns)
    for d in rows:
        writer.writerow(["" if d[c] is None else d[c] for c in columns])
    path.write_text(out.getvalue(), encoding="utf-8")
    return path
