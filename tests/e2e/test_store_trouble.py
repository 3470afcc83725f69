"""A certification whose store fails it (issue 21, items 1, 2 and 5), in this process: the verdict is
given only once it is sealed and read back; a damaged store is refused before anything is recorded;
a full disk at the start leaves a run that says it was interrupted and resumes to a verdict."""

from __future__ import annotations

import contextlib
import io
import shlex
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from rig.cli import main
from rig.store import Store, shown_status
from rig.store._store import Store as StoreClass
from tests.cli.test_run_status import _dead_pid
from tests.store.test_store_gone import _damage
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    return {"proc": tmp_path / "proc.toml", "bat": tmp_path / "bat.toml", "db": tmp_path / "r.db"}


def certify(files: dict[str, Path], *extra: str) -> tuple[int, str, str]:
    """`rig certify` of the quick procedure on the ideal simulated rig: (exit status, stdout, stderr)."""
    argv = ["certify", "--procedure", str(files["proc"]), "--bat", str(files["bat"]), "--sim", "ideal"]
    return cli(*argv, "--db", str(files["db"]), *extra)


def cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def _gone(path: Path) -> None:
    for suffix in ("", "-wal", "-shm"):
        path.with_name(path.name + suffix).unlink(missing_ok=True)


def test_a_store_deleted_mid_run_stops_it_with_no_verdict(
    files: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    original = StoreClass.append_many  # a run's entries go in at commit points (rig.store.RunWriter)

    def append_many(self: Store, items: Any) -> Any:
        items = list(items)
        if any(kind == "ShotMeasured" and payload.get("index") == 3 for _, kind, payload in items):
            _gone(files["db"])  # `rm d.db d.db-wal d.db-shm` while the run goes on
        return original(self, items)

    monkeypatch.setattr(StoreClass, "append_many", append_many)
    code, out, err = certify(files)
    assert code == 2, err
    assert err.strip().splitlines()[-1].startswith("rig: ") and "r.db is gone" in err
    assert "PASS" not in out + err and "FAIL" not in out + err and "Traceback" not in err


def test_a_store_gone_right_after_the_seal_gives_no_verdict(
    files: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    original = StoreClass.set_run_status

    def set_run_status(self: Store, run_id: str, status: str, verdict: str | None = None) -> Any:
        entry = original(self, run_id, status, verdict)
        _gone(files["db"])  # the seal committed, then the files went: nothing backs the verdict
        return entry

    monkeypatch.setattr(StoreClass, "set_run_status", set_run_status)
    code, out, err = certify(files)
    assert code == 2, err
    assert err.count("rig: ") == 1 and err.strip().splitlines()[-1].startswith("rig: ") and "r.db" in err
    assert "PASS" not in out + err and "FAIL" not in out + err


def test_a_damaged_store_is_refused_before_anything_is_recorded(files: dict[str, Path]) -> None:
    for _ in range(7):  # enough entries for a leaf page in the middle
        assert certify(files)[0] == 0
    _damage(files["db"])
    before = files["db"].read_bytes()
    code, _, err = certify(files)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "damaged" in err and "rig verify" in err
    assert files["db"].read_bytes() == before


def test_a_resume_into_a_run_whose_chain_is_broken_is_refused(files: dict[str, Path]) -> None:
    _, _, err = _interrupted_run(files)
    run = err.split("rig certify --resume ")[1].split()[0]
    with Store.open(files["db"]) as store:
        shot = store.entries(run, kinds=["ShotFired"])[0]
        count = len(store.entries())
    with contextlib.closing(sqlite3.connect(files["db"])) as db:
        db.execute("DROP TRIGGER log_no_update")
        db.execute("UPDATE log SET payload = ? WHERE seq = ?", ('{"index":1}', shot.seq))
        db.commit()
    code, _, err = cli("certify", "--resume", run, "--sim", "ideal", "--db", str(files["db"]))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"run {run}" in err and "hash mismatch" in err
    with Store.open(files["db"]) as store:
        assert len(store.entries()) == count  # nothing recorded, no device opened


def _interrupted_run(files: dict[str, Path]) -> tuple[int, str, str]:
    """A run stopped mid-way (gates configured where they are not: the aim leaves its calibration)."""
    from tests.protocols.test_run_errors import MISMEASURING_RIG

    rig = files["db"].parent / "rig.toml"
    rig.write_text(MISMEASURING_RIG)
    argv = ["certify", "--procedure", "bbcor", "--bat", str(files["bat"]), "--config", str(rig)]
    code, out, err = cli(*argv, "--db", str(files["db"]))
    assert code == 3, err
    return code, out, err


DISK_FULL = sqlite3.OperationalError("database or disk is full")


@pytest.mark.parametrize("fits", ["the interruption fits", "nothing fits"])
def test_a_full_disk_at_the_start_leaves_a_run_that_resumes(
    files: dict[str, Path], monkeypatch: pytest.MonkeyPatch, fits: str
) -> None:
    """The disk fills after the run is created: RunStarted cannot be written (and, the second
    time, neither the interruption nor the lock): the run says interrupted and resumes."""
    original = StoreClass._append
    full = {"on": True}

    def _append(self: Store, conn: Any, run_id: str | None, kind: str, *args: Any, **kw: Any) -> Any:
        created = kind in ("BatRegistered", "RunCreated", "RunOpened")  # these fitted
        if full["on"] and not created and (kind == "RunStarted" or fits == "nothing fits"):
            raise DISK_FULL
        return original(self, conn, run_id, kind, *args, **kw)

    monkeypatch.setattr(StoreClass, "_append", _append)
    if fits == "nothing fits":
        monkeypatch.setattr(StoreClass, "release_run", lambda self, held: None)  # its lock row stays
    code, out, err = certify(files)
    assert "Traceback" not in err and "PASS" not in out + err
    assert "database or disk is full" in err
    assert code == (3 if fits == "the interruption fits" else 2), err
    resume = err.split("resume with: ")[1].strip().splitlines()[0]
    if fits == "nothing fits":  # its lock row stayed (the disk was full): this process then ends
        with contextlib.closing(sqlite3.connect(files["db"])) as db:
            db.execute("UPDATE run_locks SET pid = ?", (_dead_pid(),))
            db.commit()
    with Store.open(files["db"]) as store:
        (run,) = store.runs()
        assert shown_status(store, run) == "interrupted"
        assert [e.kind for e in store.entries(run.run_id)][-1] in ("RunCreated", "RunInterrupted")
    full["on"] = False  # space freed
    argv = shlex.split(resume)
    assert argv[:3] == ["rig", "certify", "--resume"]
    code, out, err = cli(*argv[1:])
    assert code == 0, err
    assert "PASS" in out
    with Store.open(files["db"]) as store:
        assert store.verify().ok and store.runs()[0].status == "finished"
        kinds = [e.kind for e in store.entries(store.runs()[0].run_id)]
        assert kinds.count("RunStarted") == 1 and kinds[-1] == "RunStatusChanged"
