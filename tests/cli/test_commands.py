"""The commands as a user meets them: --version, the default store and RIG_DB, --json wherever the
output is data, tables that read well in a pipe, no raw Python values, a dry run that writes nothing,
a Markdown report on stdout that writes no file."""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
from importlib.metadata import version
from pathlib import Path

from tests.cli.conftest import GOOD_BAT, QUICK_PROCEDURE, rig, rig_env

BOX_DRAWING = re.compile("[\u2500-\u257f]")
PY_REPR = re.compile(r"\{'|\['|': |\bNone\b|\bTrue\b|\bFalse\b")


def test_version() -> None:
    done = rig("--version")
    assert done.returncode == 0 and done.stdout.strip() == f"rig {version('bat-rig')}"


def test_help_states_the_default_store_and_its_variable() -> None:
    text = " ".join(rig("--help").stdout.split())
    assert "rig-records.db in the working directory" in text and "RIG_DB" in text
    runs_help = " ".join(rig("runs", "--help").stdout.split())
    assert "$RIG_DB" in runs_help and "rig-records.db" in runs_help


def test_rig_db_names_the_store(store_db: Path, tmp_path: Path) -> None:
    listed = rig("runs", "--json", cwd=tmp_path, env=rig_env(RIG_DB=str(store_db)))
    assert listed.returncode == 0, listed.stderr
    assert len(json.loads(listed.stdout)) == 1
    assert rig("verify", cwd=tmp_path, env=rig_env(RIG_DB=str(store_db))).returncode == 0
    # without it, the working directory's rig-records.db, which is not there: one line, exit 2
    missing = rig("runs", cwd=tmp_path)
    assert missing.returncode == 2 and len(missing.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "rig-records.db").exists()


def test_verify_json_is_the_same_check_as_the_text(store_db: Path, tmp_path: Path) -> None:
    done = rig("verify", "--db", str(store_db), "--json")
    result = json.loads(done.stdout)
    text = rig("verify", "--db", str(store_db)).stdout
    assert done.returncode == 0 and result["ok"] is True and result["problems"] == []
    assert f"head {result['head']['seq']}:{result['head']['hash']}" in text
    assert f"ok: {result['entries_checked']} entries" in text
    altered = tmp_path / "altered.db"
    shutil.copyfile(store_db, altered)
    with sqlite3.connect(altered, isolation_level=None) as db:  # as a forger would: triggers lifted
        for (name,) in db.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'").fetchall():
            db.execute(f"DROP TRIGGER {name}")
        db.execute("UPDATE log SET payload = '{}' WHERE seq = 5")
    done = rig("verify", "--db", str(altered), "--json")
    result = json.loads(done.stdout)
    assert done.returncode == 1 and result["ok"] is False and result["problems"]
    assert "hash mismatch" in " ".join(result["problems"])


def test_report_json_is_format_json(store_db: Path) -> None:
    alias = rig("report", "last", "--db", str(store_db), "--json")
    long = rig("report", "last", "--db", str(store_db), "--format", "json")
    assert alias.returncode == 0 and alias.stdout == long.stdout
    assert json.loads(alias.stdout)["verdict"]["verdict"] in ("PASS", "FAIL")
    clash = rig("report", "last", "--db", str(store_db), "--json", "--format", "md")
    assert clash.returncode == 2 and clash.stderr.count("\n") == 1 and "--format json" in clash.stderr


def test_runs_table_in_a_pipe_keeps_every_value_whole(store_db: Path) -> None:
    (row,) = json.loads(rig("runs", "--db", str(store_db), "--json").stdout)
    table = rig("runs", "--db", str(store_db)).stdout
    assert not BOX_DRAWING.search(table) and "\x1b[" not in table  # no box drawing, no colour codes
    assert "…" not in table
    line = next(x for x in table.splitlines() if row["run_id"][:12] in x)
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells == [
        row["run_id"][:12],
        row["procedure"],
        row["bat_id"],
        "sim-ideal",
        row["started_utc"],
        row["status"],
        row["verdict"] or "",
    ]


def test_result_lines_hold_no_python_values(store_db: Path) -> None:
    """Every command that prints a result: no dict or list reprs, no None/True/False."""
    commands = [
        ("model", "cor", "--speed", "60.8", "--hoop", "1276"),
        ("model", "cor", "--speed", "60.8", "--rigid"),
        ("model", "bat", "--speed", "60.8", "--hoop", "3600", "--moi", "0.2", "--impact-from-pivot", "0.6"),
        ("shot", "--sim", "ideal", "--speed", "60.8", "--db", str(store_db.with_name("shots.db"))),
        ("runs", "--db", str(store_db)),
        ("verify", "--db", str(store_db)),
    ]
    printed = []
    for args in commands:
        done = rig(*args)
        assert done.returncode == 0, (args, done.stderr)
        assert not PY_REPR.search(done.stdout), (args, done.stdout)
        printed.append(done.stdout)
    cor = printed[0]  # the first command's output (not a second run of it)
    assert re.search(r"params\.m1 +\| +0\.145 \|", cor)  # the nested values, one per row


def test_dry_run_creates_no_database(tmp_path: Path) -> None:
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    args = ("certify", "--procedure", "proc.toml", "--bat", "bat.toml", "--sim", "ideal", "--dry-run")
    before = sorted(p.name for p in tmp_path.iterdir())
    for extra in ((), ("--db", "named.db")):
        done = rig(*args, *extra, cwd=tmp_path)
        assert done.returncode == 0 and "dry run: the procedure fits" in done.stderr, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    done = rig(*args, cwd=tmp_path, env=rig_env(RIG_DB=str(tmp_path / "env.db")))
    assert done.returncode == 0 and sorted(p.name for p in tmp_path.iterdir()) == before


def test_markdown_report_on_stdout_writes_no_file(store_db: Path, tmp_path: Path) -> None:
    done = rig("report", "last", "--db", str(store_db), "--format", "md", cwd=tmp_path)
    assert done.returncode == 0 and "## Verdict" in done.stdout and "![" not in done.stdout
    assert list(tmp_path.iterdir()) == []
    figs = tmp_path / "figs"
    done = rig(
        "report", "last", "--db", str(store_db), "--format", "md", "--figures", str(figs), cwd=tmp_path
    )
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", done.stdout)
    assert links and all(Path(link).is_file() and Path(link).parent == figs for link in links)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figs"]
