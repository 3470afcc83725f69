"""Run the `rig` CLI (or `rig-study`) in-process on input that may be extreme: exit code, stderr, runs
left behind."""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

from rig.cli import main as rig_main
from rig.store import Store
from studies.cli import main as study_main

ROOT = Path(__file__).resolve().parents[2]
QUICK_PROCEDURE = """\
[procedure]
name = "Quick BBCOR (extreme-input tests)"
standard = "bbcor"
edition = "test procedure, not a standard"
limit = 0.500
ring_check = false

[procedure.scan]
from_in = 6.5
to_in = 7.0
step_in = 0.5

[procedure.hits]
valid_hits = 2
"""
GOOD_BAT = """\
[bat]
id = "B1"
length_in = 33.0
weight_oz = 30.0
barrel = "aluminium"
hoop_hz = 3600.0
balance_point_in = 22.0
"""


def main(argv: list[str]) -> int:
    """`rig ARGV`; for an argv that starts with "rig-study", `rig-study` with the rest."""
    return study_main(argv[1:]) if argv[:1] == ["rig-study"] else rig_main(argv)


@dataclass
class Result:
    """What one CLI call did."""

    code: int | str | None
    err: str
    stray_runs: list[str]  # runs left 'running' without a recorded interruption


def run_cli(argv: list[str], db: Path | None = None) -> Result:
    """main(argv) with stdout and stderr captured; SystemExit (argparse) gives its code."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code: int | str | None = main(argv)
        except SystemExit as exc:
            code = exc.code
    return Result(code, err.getvalue(), stray_runs(db) if db is not None else [])


def stray_runs(db: Path) -> list[str]:
    """Runs still 'running' whose last entry is not RunInterrupted (no resume was offered)."""
    if not db.exists():
        return []
    with Store.open(db) as store:
        stray = []
        for run in store.runs():
            if run.status != "running":
                continue
            entries = store.entries(run.run_id)
            if not entries or entries[-1].kind != "RunInterrupted":
                stray.append(run.run_id)
        return stray


def toml_value(value: object) -> str:
    """A TOML literal (inline tables and arrays) for a parsed value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        text = repr(value)
        return {"nan": "nan", "inf": "inf", "-inf": "-inf"}.get(text, text)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items() if v is not None) + "}"
    if value is None:
        raise ValueError("TOML has no null")
    raise TypeError(type(value))


def toml_document(data: dict, table: str | None = None) -> str:
    """`data` as TOML: each top-level key a line (under [table] if given)."""
    lines = [f"[{table}]"] if table else []
    lines += [f"{k} = {toml_value(v)}" for k, v in data.items() if v is not None]
    return "\n".join(lines) + "\n"
