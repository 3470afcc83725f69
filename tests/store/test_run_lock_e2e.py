"""Two `rig certify --resume RUN` started together after a kill -9: exactly one runs the run.

Run with two CPU-bound processes beside it, as anything crossing a process boundary must be.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from collections import Counter
from pathlib import Path

import pytest

from rig.report.record import run_record
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
RIG = "import sys; from rig.cli import main; sys.exit(main())"

# A runner that kills itself (SIGKILL) right after its third shot was recorded as fired.
KILLED_RUNNER = textwrap.dedent("""
    import os, signal, sys
    from rig.protocols.procedure import Procedure
    from rig.certification import certify
    from rig.core.bat import BatSpec
    from rig.session import sim_config
    from rig.store import Store

    db, bat_path = sys.argv[1], sys.argv[2]
    fired = 0

    def killer(event):
        global fired
        if event.kind == "ShotFired":
            fired += 1
            if fired == 3:
                os.kill(os.getpid(), signal.SIGKILL)

    bat = BatSpec.load(bat_path)
    with Store.open(db) as store:
        certify(store, Procedure.load("bbcor"), bat, sim_config("lab", bat=bat), subscribers=[killer])
""")


@pytest.mark.slow
@pytest.mark.usefixtures("cpu_load")
def test_two_resumes_at_once_after_a_kill_only_one_fires(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    killed = subprocess.Popen(
        [sys.executable, "-c", KILLED_RUNNER, str(db), str(SAMPLE_BAT)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _, killed_err = killed.communicate(timeout=180)
    assert killed.returncode == -9, killed_err
    with Store.open(db) as store:
        (run,) = store.open_runs()
        stale = store.run_lock_holder(run.run_id)
        before = store.entries(run.run_id)
    assert stale is not None and stale.pid == killed.pid  # the killed runner's lock is left behind

    resume = [sys.executable, "-c", RIG, "certify", "--resume", run.run_id, "--sim", "lab", "--db", str(db)]
    procs = [
        subprocess.Popen(resume, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    outputs = [p.communicate(timeout=300) for p in procs]
    results = [(p.pid, p.returncode, out, err) for p, (out, err) in zip(procs, outputs, strict=True)]

    codes = sorted(code for _, code, _, _ in results)
    assert codes[0] in (0, 1) and codes[1] == 2, results
    (winner,) = [r for r in results if r[1] in (0, 1)]
    (loser,) = [r for r in results if r[1] == 2]
    # One clear line: who holds the run (the winner's host and pid), or, when a loaded machine
    # started the loser only after the winner had finished, that the run is finished.
    lines = loser[3].splitlines()
    assert len(lines) == 1 and "Traceback" not in loser[3], loser[3]
    if "already being run" in lines[0]:
        assert lines[0].startswith(f"rig: run {run.run_id} is already being run by host ")
        assert f" pid {winner[0]} since " in lines[0]
    else:
        assert f"run {run.run_id} is already finished" in lines[0], lines[0]
    assert "shot" not in loser[2]  # it never reached the runner: nothing fired
    assert "PASS" in winner[2] or "FAIL" in winner[2]

    with Store.open(db) as store:
        assert store.verify().ok  # which includes: no shot number used twice
        after = store.entries(run.run_id)
        assert store.run(run.run_id).status == "finished"
        assert store.run_lock_holder(run.run_id) is None  # released
    assert after[: len(before)] == before
    new = after[len(before) :]
    kinds = Counter(e.kind for e in new)
    assert kinds["RunResumed"] == 1 and kinds["RunFinished"] == 1 and kinds["RunStatusChanged"] == 1
    (broken,) = [e.payload for e in new if e.kind == "RunLockBroken"]
    assert broken["holder"]["pid"] == killed.pid and broken["taken_by"]["pid"] == winner[0]
    assert broken["reason"].startswith(f"process {killed.pid} no longer runs")
    with Store.open(db) as store:  # the certificate lists the broken lock among the interruptions
        events = run_record(store, run.run_id)["interruptions"]
    assert [i["kind"] for i in events[-2:]] == ["RunLockBroken", "RunResumed"]
    host = broken["holder"]["host"]
    assert events[-2]["reason"] == f"lock of host {host} pid {killed.pid} broken: {broken['reason']}"
    fired = Counter(e.payload["index"] for e in after if e.kind == "ShotFired")
    requested = Counter(e.payload["index"] for e in after if e.kind == "ShotRequested")
    assert set(fired.values()) == {1} and set(requested.values()) == {1}


def schema(path: Path) -> list[tuple[str, str]]:
    """The file's tables, indexes and triggers (name and SQL), sorted."""
    import sqlite3

    conn = sqlite3.connect(path)
    try:
        return sorted(conn.execute("SELECT name, sql FROM sqlite_master WHERE sql IS NOT NULL"))
    finally:
        conn.close()


def test_a_version_1_file_still_resumes_verifies_and_reports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run interrupted in a file of schema 1 (no lock table) is resumed by today's software."""
    import sqlite3

    from rig.cli import main
    from rig.store import _schema

    db = tmp_path / "r.db"
    Store.open(db, chain_format=1).close()  # entries as schema 1 wrote them: one chain
    code = main(
        ["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", "faulty", "--db", str(db)]
    )
    assert code == 3, capsys.readouterr().err  # the faulty scene interrupts the run
    run_id = capsys.readouterr().err.split("rig certify --resume ")[1].split()[0]
    conn = sqlite3.connect(db)  # back to schema 1, as files written before the lock table are
    conn.execute("DROP TABLE run_locks")
    conn.execute("DROP VIEW shots")  # schema 4
    conn.execute("DROP VIEW runs_summary")
    conn.execute("DROP INDEX log_by_chain")  # and before chain format 2
    conn.execute("ALTER TABLE log DROP COLUMN chain")
    conn.execute("ALTER TABLE log DROP COLUMN chain_seq")
    conn.execute("DROP TABLE store_meta")
    conn.execute("DELETE FROM schema_version WHERE version > 1")
    conn.commit()
    conn.close()
    monkeypatch.setattr(_schema, "MIGRATIONS", _schema.MIGRATIONS[:1])
    monkeypatch.setattr(_schema, "SCHEMA_VERSION", 1)
    Store.open(tmp_path / "v1.db").close()  # what the released version 1 makes
    monkeypatch.undo()
    assert schema(db) == schema(tmp_path / "v1.db")

    assert main(["verify", "--db", str(db)]) == 0
    assert main(["report", run_id, "--db", str(db), "--format", "json"]) == 0
    capsys.readouterr()
    for _ in range(5):  # the resumed run may meet the faulty rig's next fault too: resume again
        code = main(["certify", "--resume", run_id, "--sim", "lab", "--db", str(db)])
        if code != 3:
            break
    assert code in (0, 1), capsys.readouterr().err
    assert main(["verify", "--db", str(db)]) == 0
    with Store.open(db) as store:
        assert store.run(run_id).status == "finished"
    conn = sqlite3.connect(db)
    versions = [v for (v,) in conn.execute("SELECT version FROM schema_version ORDER BY version")]
    assert versions == list(range(1, _schema.SCHEMA_VERSION + 1))
    assert conn.execute("SELECT value FROM store_meta").fetchone() == ("1",)  # it stays one chain
    conn.close()
