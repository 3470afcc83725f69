"""The analysts' views (rig.store: `shots`, `runs_summary`) written as CSV or Parquet, typed.

A file is written next to its final name and moved into place only when complete, so a failed
export never leaves half a file nor replaces an older one. Parquet goes through pyarrow,
imported only when asked for (it is large and `rig` starts for every command).
"""

from __future__ import annotations

import contextlib
import csv
import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from rig.core.errors import ConfigError
from rig.store import Store
from rig.store._views import VIEW_COLUMNS, VIEWS, ColumnType

if TYPE_CHECKING:
    import pyarrow as pa

FORMATS = ("csv", "parquet")
STDOUT = "-"


def check_request(view: str, fmt: str, output: str) -> None:
    """Refuse an unknown view or format, Parquet to stdout, and an output that cannot be written."""
    if view not in VIEW_COLUMNS:
        raise ConfigError(f"no view {view!r}; the views are {', '.join(VIEWS)}", source="--view")
    if fmt not in FORMATS:
        raise ConfigError(f"no format {fmt!r}; the formats are {', '.join(FORMATS)}", source="--format")
    if output == STDOUT:
        if fmt != "csv":
            raise ConfigError("Parquet is binary: give a file, not '-'", source="--output")
        return
    path = Path(output)
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder, not a file", source="--output")
    if not path.parent.is_dir():
        raise ConfigError(f"{path}: the folder {path.parent} does not exist", source="--output")


Rows = Sequence[dict[str, Any]]
Columns = Sequence[tuple[str, ColumnType]]


def write_csv(rows: Rows, columns: Columns, out: IO[str]) -> None:
    """A header, then one line per row: floats as Python writes them (exact), bools true/false, NULL empty."""
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([name for name, _ in columns])
    for row in rows:
        writer.writerow([_csv_cell(row[name]) for name, _ in columns])


def _csv_cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def arrow_table(rows: Rows, columns: Columns) -> pa.Table:
    """The rows as an Arrow table with one typed column each (float64, int64, bool, string)."""
    import pyarrow as pa

    types = {"text": pa.string(), "int": pa.int64(), "float": pa.float64(), "bool": pa.bool_()}
    schema = pa.schema([pa.field(name, types[kind]) for name, kind in columns])
    return pa.Table.from_pylist(list(rows), schema=schema)


def export(
    store: Store, view: str, fmt: str, output: str, run_id: str | None = None, stdout: IO[str] | None = None
) -> int:
    """Write a view (of one run or all) to `output` ('-': stdout, CSV only); returns the rows written."""
    check_request(view, fmt, output)
    rows = store.view_rows(view, run_id)  # read before the file is touched: a bad store writes nothing
    columns = VIEW_COLUMNS[view]
    if output == STDOUT:
        assert stdout is not None, "stdout is needed for '-'"
        write_csv(rows, columns, stdout)
        return len(rows)
    if fmt == "csv":
        atomic_write(Path(output), lambda tmp: _csv_file(tmp, rows, columns))
    else:
        import pyarrow.parquet as pq

        table = arrow_table(rows, columns)
        atomic_write(Path(output), lambda tmp: pq.write_table(table, tmp))
    return len(rows)


def _csv_file(path: Path, rows: Rows, columns: Columns) -> None:
    with path.open("w", encoding="utf-8", newline="") as out:
        write_csv(rows, columns, out)


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """Write through a temporary file in the same folder, then move it onto `path`."""
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot write there ({exc.strerror or exc})", source="--output") from None
    os.close(fd)
    tmp = Path(name)
    try:
        os.chmod(tmp, 0o644)  # mkstemp makes it private; an export is for others to read
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot write ({exc.strerror or exc})", source="--output") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
