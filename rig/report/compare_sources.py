"""Where `rig compare` reads results: a record store, or a `runs_summary` file written by `rig export`.

The kind is told by the content, not the name: a SQLite file (or a postgresql:// URL) is a store,
read through its `runs_summary` view; a file starting with Parquet's magic is Parquet; anything
else must be UTF-8 CSV with the view's header. A file is read within DATA_BYTES (rig.core.files);
one that is binary, endless, nested, from other software or lacks a column is refused in one
line naming it (ConfigError).
"""

from __future__ import annotations

import csv
import io
import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rig.core.errors import ConfigError
from rig.core.files import DATA_BYTES, number_cell, read_bounded
from rig.quality.compare import Result, results
from rig.store import Store, is_url
from rig.store._views import VIEW_COLUMNS

WHAT = "a record store or a runs_summary export (rig export --view runs_summary)"
SQLITE_MAGIC = b"SQLite format 3\x00"
PARQUET_MAGIC = b"PAR1"
NEEDED = ("run_id", "bat_id", "procedure", "status", "mean", "expanded_uncertainty")
TYPES = dict(VIEW_COLUMNS["runs_summary"])


def load(source: str) -> list[Result]:
    """The finished results held by `source` (a store's path or URL, or an exported file)."""
    if is_url(source):
        return _from_store(source)
    if _head(source) == SQLITE_MAGIC:
        return _from_store(source)
    raw = read_bounded(source, DATA_BYTES, WHAT, binary=True)
    rows = _parquet_rows(raw, source) if raw.startswith(PARQUET_MAGIC) else _csv_rows(raw, source)
    return results(rows)


def _head(source: str) -> bytes:
    """The first 16 bytes of a regular file (b'' for anything else: read_bounded then refuses it)."""
    try:
        fd = os.open(source, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return b""  # missing or unreadable: read_bounded says which
    try:
        return os.read(fd, 16) if stat.S_ISREG(os.fstat(fd).st_mode) else b""
    finally:
        os.close(fd)


def _from_store(source: str) -> list[Result]:
    with Store.open(source, create=False, readonly=True) as store:
        return results(store.view_rows("runs_summary"))


def _check_columns(names: list[str], source: str) -> None:
    missing = [name for name in NEEDED if name not in names]
    if missing:
        raise ConfigError(
            f"not {WHAT}: no column {', '.join(missing)} (its columns: {', '.join(names[:12]) or 'none'})",
            source=source,
        )


def _csv_rows(raw: bytes, source: str) -> list[dict[str, Any]]:
    if b"\x00" in raw:
        raise ConfigError(f"not {WHAT}: it holds NUL bytes", source=source)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not {WHAT}: not UTF-8 text (byte {exc.start})", source=source) from None
    try:
        reader = csv.reader(io.StringIO(text, newline=""), strict=True)
        header = next(reader, [])
        _check_columns(header, source)
        rows = []
        for line, cells in enumerate(reader, 2):
            if len(cells) != len(header):
                raise ConfigError(
                    f"not {WHAT}: line {line} has {len(cells)} cells, the header {len(header)}", source=source
                )
            rows.append(
                {name: _cell(name, cell, line, source) for name, cell in zip(header, cells, strict=True)}
            )
    except csv.Error as exc:
        raise ConfigError(f"not {WHAT}: {exc}", source=source) from None
    return rows


def _cell(name: str, cell: str, line: int, source: str) -> Any:
    """A CSV cell typed as the view types its column (empty: NULL)."""
    if cell == "" or TYPES.get(name) != "float":
        return cell or None
    return number_cell(cell, name, f"{source}: line {line}")


def _parquet_rows(raw: bytes, source: str) -> list[dict[str, Any]]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(pa.BufferReader(raw))
    except (pa.ArrowException, OSError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(f"not {WHAT}: unreadable Parquet ({first[:120]})", source=source) from None
    _check_columns(table.column_names, source)
    flat = (pa.types.is_floating, pa.types.is_integer, pa.types.is_string, pa.types.is_large_string)
    for name in NEEDED:
        kind = table.schema.field(name).type
        if not any(test(kind) for test in flat) and not pa.types.is_null(kind):
            raise ConfigError(f"not {WHAT}: column {name} holds {kind}, not plain values", source=source)
    rows: list[Mapping[str, Any]] = table.select(list(NEEDED) + _optional(table.column_names)).to_pylist()
    return [_typed(row, source) for row in rows]


def _optional(names: list[str]) -> list[str]:
    return [name for name in ("rig", "k", "started_utc") if name in names]


def _typed(row: Mapping[str, Any], source: str) -> dict[str, Any]:
    """A Parquet row with its number columns numbers and its text columns text."""
    out = dict(row)
    for name in ("mean", "expanded_uncertainty", "k"):
        value = out.get(name)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise ConfigError(f"not {WHAT}: column {name} holds {type(value).__name__}", source=source)
    return out


def shown_source(source: str) -> str:
    """A source as printed: a URL's password masked, a path as given."""
    from rig.store import safe_url

    return safe_url(source) if is_url(source) else str(Path(source))
