"""CCOR-against-speed points: one measured cylindrical COR per ball and inbound speed.

CSV columns: `speed_m_s`, `ccor` (required), `u_ccor` (its standard uncertainty, k = 1) and
`ball_id` (optional). Lines starting with `#` and blank lines are skipped. A hostile file (empty,
binary, larger than MAX_BYTES, a missing column, a cell that is not a finite number) is refused
with one line naming the file and, for a cell, its line.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from rig.core.errors import ConfigError, listed
from rig.core.files import number_cell, read_bounded

COLUMNS = ("speed_m_s", "ccor", "u_ccor", "ball_id")
REQUIRED = ("speed_m_s", "ccor")
MAX_BYTES = 10_000_000  # ~200 000 rows; a lab's CCOR test has tens to hundreds
SPEED_RANGE = (1.0, 100.0)  # m/s, as `rig model` bounds a ball's speed


@dataclass(frozen=True)
class CcorPoint:
    """One ball's CCOR at one inbound speed."""

    speed_m_s: float
    ccor: float
    u_ccor: float | None = None
    ball_id: str | None = None
    source: str = ""  # where it came from (file and line, or the store's test), for messages


@dataclass(frozen=True)
class CcorData:
    """The points and the bytes their provenance hashes."""

    points: tuple[CcorPoint, ...]
    blob: bytes
    name: str


def check_point(p: CcorPoint) -> CcorPoint:
    """ConfigError (naming the point's source) for a value no CCOR test can give."""
    lo, hi = SPEED_RANGE
    if not lo <= p.speed_m_s <= hi:
        raise ConfigError(f"speed_m_s {p.speed_m_s:g} outside {lo:g}-{hi:g} m/s", source=p.source)
    if not 0.0 < p.ccor < 1.0:
        raise ConfigError(f"ccor {p.ccor:g} outside 0-1 (exclusive)", source=p.source)
    if p.u_ccor is not None and not 0.0 < p.u_ccor < 1.0:
        raise ConfigError(f"u_ccor {p.u_ccor:g} must lie between 0 and 1 (exclusive)", source=p.source)
    return p


def parse_ccor_csv(text: str, name: str) -> list[CcorPoint]:
    """The points of a CCOR CSV text; `name` is how messages call the file."""
    lines = [(n, s) for n, s in enumerate(text.splitlines(), start=1) if s.strip()]
    lines = [(n, s) for n, s in lines if not s.lstrip().startswith("#")]
    if not lines:
        raise ConfigError("no header and no rows", source=name)
    try:
        rows = list(csv.reader(io.StringIO("\n".join(s for _, s in lines))))
    except csv.Error as exc:
        raise ConfigError(f"not a readable CSV file: {exc}", source=name) from None
    header = [c.strip() for c in rows[0]]
    where = f"{name}: line {lines[0][0]}"
    unknown = [c for c in header if c not in COLUMNS]
    if unknown:
        raise ConfigError(f"unknown column(s) {listed(unknown)}; known: {', '.join(COLUMNS)}", source=where)
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise ConfigError(f"missing column(s) {', '.join(missing)}", source=where)
    twice = sorted({c for c in header if header.count(c) > 1})
    if twice:
        raise ConfigError(f"column(s) {listed(twice)} appear twice", source=where)
    if len(rows) < 2:
        raise ConfigError("a header but no rows", source=name)
    points = []
    for (line_no, _), cells in zip(lines[1:], rows[1:], strict=True):
        where = f"{name}: line {line_no}"
        if len(cells) != len(header):
            raise ConfigError(f"{len(cells)} cells, the header has {len(header)}", source=where)
        row = {k: v.strip() for k, v in zip(header, cells, strict=True)}
        for column in REQUIRED:
            if not row[column]:
                raise ConfigError(f"{column} is empty", source=where)
        u = row.get("u_ccor") or ""
        ball = row.get("ball_id") or ""
        points.append(
            check_point(
                CcorPoint(
                    speed_m_s=number_cell(row["speed_m_s"], "speed_m_s", where),
                    ccor=number_cell(row["ccor"], "ccor", where),
                    u_ccor=number_cell(u, "u_ccor", where) if u else None,
                    ball_id=ball or None,
                    source=where,
                )
            )
        )
    return points


def load_ccor_csv(path: str | Path) -> CcorData:
    """Read a CCOR CSV file; ConfigError names the file (and the line) and the cause."""
    path = Path(path)
    raw = read_bounded(path, MAX_BYTES, "a CCOR data file")
    if not raw.strip():
        raise ConfigError("empty file", source=str(path))
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a UTF-8 text file (byte {exc.start})", source=str(path)) from None
    return CcorData(tuple(parse_ccor_csv(text, str(path))), raw, str(path))


def _cell(value: float | str | None) -> str:
    if value is None:
        return ""
    return value if isinstance(value, str) else repr(float(value))


def write_ccor_csv(points: list[CcorPoint], path: str | Path, comments: tuple[str, ...] = ()) -> Path:
    """Write points in the CSV format (u_ccor and ball_id only when some point has them)."""
    columns = ["speed_m_s", "ccor"]
    columns += [c for c in ("u_ccor", "ball_id") if any(getattr(p, c) is not None for p in points)]
    out = io.StringIO()
    for c in comments:
        out.write(f"# {c}\n")
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(columns)
    for p in points:
        writer.writerow([_cell(getattr(p, c)) for c in columns])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(out.getvalue(), encoding="utf-8")
    return path
