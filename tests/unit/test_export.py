"""`rig export`: the views as CSV and Parquet, read back and checked against the values written
into a hand-made run; bad input is one line, exit 2, and leaves files as they were."""

from __future__ import annotations

import contextlib
import csv
import io
import os
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from rig.cli import main
from rig.store import Store
from tests.store import handmade
from tests.unit.clirun import run_cli


@pytest.fixture
def db(tmp_path: Path) -> tuple[Path, list[dict[str, Any]], dict[str, Any]]:
    """A store with the hand-made run and a second bat's run with no shots; the expected rows."""
    path = tmp_path / "r.db"
    with Store.open(path) as store:
        run_id = handmade.build(store)
        fired = {e.payload["index"]: e.t_utc for e in store.entries(run_id, kinds=["ShotFired"])}
        closing = store.entries(run_id, kinds=["RunStatusChanged"])[0].t_utc
        summary = handmade.expected_summary(run_id, store.run(run_id).started_utc, closing)
        store.register_bat("OTHER", {"id": "OTHER"})
        store.create_run("bbcor", "OTHER", {})
    return path, handmade.expected_shots(run_id, fired), summary


def _cell(value: Any) -> str:
    """How a value is expected in the CSV (independent spelling: true/false, empty for NULL)."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def _stdout(argv: list[str]) -> tuple[int | str | None, str, str]:
    """main(argv): exit code, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code: int | str | None = main(argv)
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def test_shots_as_csv_parse_back_to_the_values_written(db: tuple[Path, list, dict], tmp_path: Path) -> None:
    path, shots, _ = db
    out = tmp_path / "shots.csv"
    argv = ["export", "--db", str(path), "--view", "shots", "--format", "csv", "--output", str(out)]
    result = run_cli(argv)
    assert result.code == 0, result.err
    assert result.err == f"wrote 5 rows of shots to {out}\n"
    with out.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [r["shot_index"] for r in rows] == ["1", "2", "3", "4", "6"]
    assert rows == [{k: _cell(v) for k, v in shot.items()} for shot in shots]
    # numbers round-trip exactly; validity reads back as a bool
    assert [float(r["metric"]) for r in rows[:3]] == [0.451, 0.462, 0.473]
    assert [r["valid"] for r in rows] == ["true", "false", "false", "false", ""]
    assert rows[2]["reasons"] == "SPEED_OUT_OF_TOLERANCE,MISSED_GATE"
    assert oct(os.stat(out).st_mode & 0o777) == "0o644"


def test_csv_to_stdout_one_run(db: tuple[Path, list, dict]) -> None:
    path, _, summary = db
    run = summary["run_id"]
    argv = ["export", "--db", str(path), "--view", "runs_summary", "--run", run[:8], "-o", "-"]
    code, out, err = _stdout(argv)
    assert code == 0, err
    rows = list(csv.DictReader(io.StringIO(out)))
    assert rows == [{k: _cell(v) for k, v in summary.items()}]
    code, out, err = _stdout(["export", "--db", str(path), "--view", "runs_summary", "-o", "-"])
    assert code == 0 and len(list(csv.DictReader(io.StringIO(out)))) == 2  # both runs


def test_parquet_reads_back_typed(db: tuple[Path, list, dict], tmp_path: Path) -> None:
    path, shots, summary = db
    out = tmp_path / "shots.parquet"
    argv = ["export", "--db", str(path), "--view", "shots", "--format", "parquet", "--output", str(out)]
    assert run_cli(argv).code == 0
    table = pq.read_table(out)
    types = {f.name: f.type for f in table.schema}
    assert types["metric"] == pa.float64() and types["location_in"] == pa.float64()
    assert types["valid"] == pa.bool_() and types["shot_index"] == pa.int64()
    assert types["reasons"] == pa.string() and types["run_id"] == pa.string()
    assert table.to_pylist() == shots
    assert table.column("valid").null_count == 1  # the shot with no outcome yet

    out = tmp_path / "runs.parquet"
    argv = ["export", "--db", str(path), "--view", "runs_summary", "--format", "parquet", "-o", str(out)]
    assert run_cli([*argv, "--run", summary["run_id"]]).code == 0
    table = pq.read_table(out)
    assert table.to_pylist() == [summary]
    assert table.schema.field("expanded_uncertainty").type == pa.float64()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--view", "shot", "-o", "-"], "rig: --view: no view 'shot'; the views are shots, runs_summary"),
        (["--view", "shots", "--format", "xlsx", "-o", "-"], "rig: --format: no format 'xlsx'"),
        (["--view", "shots", "--format", "parquet", "-o", "-"], "rig: --output: Parquet is binary"),
        (["--view", "shots", "--run", "nope", "-o", "-"], "rig: no run 'nope'; known runs:"),
    ],
)
def test_bad_requests_are_one_line(db: tuple[Path, list, dict], extra: list[str], message: str) -> None:
    path, _, _ = db
    code, out, err = _stdout(["export", "--db", str(path), *extra])
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(message), err


def test_a_file_that_is_not_a_store_is_left_untouched(tmp_path: Path) -> None:
    notes = tmp_path / "notes.db"
    notes.write_bytes(b"shot 1: 0.45\n")
    result = run_cli(["export", "--db", str(notes), "--view", "shots", "-o", str(tmp_path / "x.csv")])
    assert result.code == 2 and result.err.count("\n") == 1
    assert "not a SQLite database" in result.err and str(notes) in result.err
    assert notes.read_bytes() == b"shot 1: 0.45\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.db"]  # no output, no -wal
    missing = tmp_path / "missing.db"
    result = run_cli(["export", "--db", str(missing), "--view", "shots", "-o", "-"])
    assert result.code == 2 and result.err == f"rig: {missing}: no such store\n" and not missing.exists()


def test_an_unwritable_output_is_one_line_and_an_old_file_survives(
    db: tuple[Path, list, dict], tmp_path: Path
) -> None:
    path, _, _ = db
    base = ["export", "--db", str(path), "--view", "shots", "-o"]
    nowhere = tmp_path / "no" / "such"
    result = run_cli([*base, str(nowhere / "x.csv")])
    assert result.err == f"rig: --output: {nowhere / 'x.csv'}: the folder {nowhere} does not exist\n"
    assert result.code == 2 and not nowhere.exists()
    result = run_cli([*base, str(tmp_path)])
    assert result.code == 2 and result.err == f"rig: --output: {tmp_path}: is a folder, not a file\n"
    old = tmp_path / "old.csv"
    old.write_text("yesterday's export\n")
    result = run_cli([*base, str(old), "--run", "nope"])  # refused after the output was checked
    assert result.code == 2 and old.read_text() == "yesterday's export\n"
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


@pytest.mark.parametrize(
    "argv",
    [
        ["modal", "analyze", "missing-recording.csv", "--json"],
        ["runs", "--db", "missing-store.db", "--json"],
        ["sync", "--from", "missing-store.db", "--to", "lab.db", "--json"],
    ],
)
def test_with_json_an_error_is_a_json_object_too(
    argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 13, finding 7: with --json, errors printed nothing on stdout."""
    import json

    from rig.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    out, err = capsys.readouterr()
    line = err.strip()
    assert line.startswith("rig: ") and "\n" not in line
    error = json.loads(out)["error"]
    assert error["message"] == line.removeprefix("rig: ") and error["exit_status"] == 2
    assert error["kind"].isidentifier()
