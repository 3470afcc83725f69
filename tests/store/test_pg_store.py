"""The store on PostgreSQL: the same records as on SQLite, several rigs at once, bad input named.

Each test gets a fresh database on the session's throwaway cluster (tests/pgfixtures.py).
"""

from __future__ import annotations

import json
import multiprocessing
import re
import sqlite3
import subprocess
import sys
from pathlib import Path
from typing import Any

import psycopg
import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store, StoreFileError
from rig.store._sync import sync

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
QUICK = ROOT / "tests" / "tui" / "quick-bbcor.toml"
_VOLATILE = re.compile(
    r"[0-9a-f]{32}|R-[0-9a-f]{12}|\d{4}-\d\d-\d\dT[0-9:.+]+|[0-9a-f]{64}|session-[0-9a-f]+"
    r"|'(host_time_s|t_s)': [0-9.e+-]+"
)


def _same(record: object) -> str:
    """A record with its ids (the run's, the report's made of it), times, host clocks and hashes
    blanked (they differ between any two runs)."""
    return _VOLATILE.sub("*", repr(record))


def test_a_certification_records_the_same_on_postgresql_as_on_sqlite(pg_url: str, tmp_path: Path) -> None:
    records = {}
    for where in (pg_url, str(tmp_path / "r.db")):
        with Store.open(where) as store:
            out = certify(store, Procedure.load(QUICK), BAT, sim_config("ideal", bat=BAT))
            assert out.status == "finished"
            report = store.verify()
            assert report.ok, report
            entries = store.entries(out.run_id)
            records[store.engine] = (
                # device traffic interleaves by thread timing: its chunks differ between any two runs
                [(e.chain_seq, e.kind, _same(e.payload) if e.kind != "Traffic" else "") for e in entries],
                _same(
                    {
                        k: v
                        for k, v in run_record(store, out.run_id).items()
                        if k not in ("anchor", "coverage")
                    }
                ),
                [_same(r) for r in store.view_rows("shots", out.run_id)],
            )
    assert records["postgresql"] == records["sqlite"]


def _rig(url: str, name: str, n: int) -> None:
    with Store.open(url) as store:
        run = store.create_run("bbcor", "B", {"rig": name})
        for i in range(n):
            store.append(run, "ShotFired", {"shot": i, "rig": name})
        store.set_run_status(run, "finished", "PASS")


@pytest.mark.usefixtures("cpu_load")
def test_four_rigs_appending_at_once_keep_every_chain_whole(pg_url: str) -> None:
    with Store.open(pg_url) as store:
        store.register_bat("B", {})
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_rig, args=(pg_url, f"rig-{k}", 40)) for k in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(180)
        assert p.exitcode == 0
    with Store.open(pg_url, create=False) as store:
        assert store.verify().ok
        runs = store.runs()
        assert len(runs) == 4 and {r.status for r in runs} == {"finished"}
        for run in runs:
            numbers = [e.chain_seq for e in store.entries(run.run_id)]
            assert numbers == list(range(1, 43))  # RunCreated, 40 shots, RunStatusChanged
        lab = [e.kind for e in store.entries() if e.run_id is None]
        assert lab.count("RunOpened") == lab.count("RunSealed") == 4


def test_tampering_on_postgresql_is_found_like_on_sqlite(pg_url: str) -> None:
    with Store.open(pg_url) as store:
        out = certify(store, Procedure.load(QUICK), BAT, sim_config("ideal", bat=BAT))
        target = [e for e in store.entries(out.run_id) if e.kind == "ShotFired"][1]
    with psycopg.connect(pg_url, autocommit=True) as db:  # the owner can drop the trigger; a forger would
        db.execute("ALTER TABLE log DISABLE TRIGGER log_no_update")
        db.execute("UPDATE log SET payload = '{}' WHERE seq = %s", (target.seq,))
    with Store.open(pg_url) as store:
        problems = "\n".join(store.verify().problems)
    assert f"run {out.run_id} entry {target.chain_seq}: hash mismatch" in problems
    assert "append-only triggers removed: log_no_update" in problems


def test_the_append_only_trigger_refuses_an_edit(pg_url: str) -> None:
    with Store.open(pg_url) as store:
        store.register_bat("B", {})
    with psycopg.connect(pg_url, autocommit=True) as db, pytest.raises(psycopg.Error, match="append-only"):
        db.execute("UPDATE log SET kind = 'X'")


def test_a_rig_file_syncs_into_the_lab_database(pg_url: str, tmp_path: Path) -> None:
    rig = tmp_path / "rig.db"
    with Store.open(rig) as store:
        run = certify(store, Procedure.load(QUICK), BAT, sim_config("lab", bat=BAT)).run_id
    with Store.open(rig) as source, Store.open(pg_url) as lab:
        first = sync(source, lab)
        again = sync(source, lab)
        assert first.runs_copied == 1 and again.entries_copied == 0
        assert [(e.chain_seq, e.hash) for e in lab.entries(run)] == [
            (e.chain_seq, e.hash) for e in source.entries(run)
        ]
        assert lab.view_rows("runs_summary") == source.view_rows("runs_summary")
        assert lab.verify().ok


def test_bad_databases_are_one_line_and_exit_2(
    pg_url: str, pg_cluster: object, capsys: pytest.CaptureFixture[str]
) -> None:
    wrong = re.sub(r"//([^:]+):[^@]+@", r"//\1:nope@", pg_url)
    assert main(["runs", "--db", wrong]) == 2
    err = capsys.readouterr().err.strip()
    assert "password authentication failed" in err and "nope" not in err and err.count("\n") == 0
    assert main(["runs", "--db", pg_url]) == 2  # an empty database is not a store (reading)
    assert "an empty database, not a store" in capsys.readouterr().err
    with psycopg.connect(pg_url, autocommit=True) as db:
        db.execute("CREATE TABLE customers (id int)")
    assert main(["runs", "--db", pg_url]) == 2
    assert "not a rig store; refusing to touch it" in capsys.readouterr().err


def test_a_newer_schema_is_refused(pg_url: str) -> None:
    Store.open(pg_url).close()
    with psycopg.connect(pg_url, autocommit=True) as db:
        db.execute("INSERT INTO schema_version VALUES (99, 'later')")
    with pytest.raises(StoreFileError, match="written by newer software"):
        Store.open(pg_url)


_CHILD = """
import json, subprocess, sys
from rig.cli import main
from rig.report import live
url, bat, quick, stop = sys.argv[1], sys.argv[2], sys.argv[3], json.loads(sys.argv[4])
shown = live.LiveConsole.__call__
measured = 0
def stop_the_server(self, event):  # the rig's console sees each event: stop the database at the third shot
    global measured
    shown(self, event)
    if event.kind == "ShotMeasured":
        measured += 1
        if measured == 3:
            subprocess.run(stop, check=True, capture_output=True, cwd="/")
live.LiveConsole.__call__ = stop_the_server
sys.exit(main(["certify", "--procedure", quick, "--bat", bat, "--sim", "ideal", "--db", url]))
"""


@pytest.mark.usefixtures("cpu_load")
def test_the_server_going_away_mid_run_loses_nothing_and_the_run_resumes(
    pg_url: str, pg_cluster: Any
) -> None:
    """The database stops during `rig certify` (another process): it exits 2 with one line naming the
    lost connection (password masked), every entry committed before stays whole, and once the server
    is back the run resumes to its verdict."""
    stop = pg_cluster._command("pg_ctl", "stop", "-D", str(pg_cluster.data_dir), "-m", "immediate", "-w")
    child = subprocess.run(
        [
            sys.executable,
            "-c",
            _CHILD,
            pg_url,
            str(ROOT / "protocols/examples/sample-bat.toml"),
            str(QUICK),
            json.dumps(stop),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    pg_cluster.stopped = True
    assert child.returncode == 2, child.stderr
    errors = [line for line in child.stderr.splitlines() if line.startswith("rig: ")]
    assert len(errors) == 1 and "Traceback" not in child.stderr
    assert "the database connection failed" in errors[0] and "resumable once it is back" in errors[0]
    assert pg_cluster.password not in child.stderr
    pg_cluster.start()
    with Store.open(pg_url) as store:
        assert store.verify().ok  # nothing half-written
        (run,) = store.runs()
        kinds = [e.kind for e in store.entries(run.run_id)]
        assert kinds.count("ShotMeasured") >= 3 and run.status == "running"
        done = certify(store, Procedure.load(QUICK), BAT, sim_config("ideal", bat=BAT), run_id=run.run_id)
        assert done.status == "finished", done.reason
        assert store.verify().ok
        assert "RunLockBroken" in [e.kind for e in store.entries(run.run_id)]  # the dead rig's lock


def test_sqlite_stays_the_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["runs"]) == 2  # no store yet: reading does not create one
    with Store.open(tmp_path / "rig-records.db") as store:
        assert store.engine == "sqlite" and store.chain_format == 2
    assert sqlite3.connect(tmp_path / "rig-records.db").execute("SELECT count(*) FROM log").fetchone() == (0,)


def test_export_and_one_run_verification_work_on_postgresql(
    pg_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    csvs = {}
    for name, where in (("pg", pg_url), ("sqlite", str(tmp_path / "r.db"))):
        with Store.open(where) as store:
            run = certify(store, Procedure.load(QUICK), BAT, sim_config("ideal", bat=BAT)).run_id
            fired = len(store.entries(run, kinds=["ShotFired"]))
        assert main(["verify", "--db", where, "--run", run]) == 0
        assert main(["export", "--db", where, "--view", "shots", "--format", "csv", "--output", "-"]) == 0
        out = capsys.readouterr().out
        assert "chain intact" in out.splitlines()[0]
        csvs[name] = _VOLATILE.sub("*", out[out.index("run_id,") :])
    assert csvs["pg"] == csvs["sqlite"] and csvs["pg"].count("\n") == 1 + fired  # the header, a row per shot
