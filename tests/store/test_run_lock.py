"""One runner per run: the lock row in the store, its refusal, its heartbeat and stale locks."""

from __future__ import annotations

import os
import socket
import subprocess
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from rig.core.errors import StoreError
from rig.store import RecordRefused, RunLocked, Store
from rig.store._lock import Heartbeat


@pytest.fixture
def db(tmp_path: Path) -> tuple[Path, str]:
    """A store file with one running run: (path, run id)."""
    path = tmp_path / "rig.db"
    with Store.open(path) as store:
        store.register_bat("B-1", {})
        run = store.create_run("bbcor", "B-1", {})
    return path, run


def plant(path: Path, run: str, host: str, pid: int, heartbeat: datetime, lease_s: float = 30.0) -> None:
    """A lock row as another runner would have left it (written with plain SQL)."""
    import sqlite3

    conn = sqlite3.connect(path)
    stamp = heartbeat.isoformat(timespec="microseconds")
    conn.execute(
        "INSERT INTO run_locks (run_id, owner, host, pid, since_utc, heartbeat_utc, lease_s) "
        "VALUES (?, ?, ?, ?, ?, ?, ?)",
        (run, "their-token", host, pid, stamp, stamp, lease_s),
    )
    conn.commit()
    conn.close()


def dead_pid() -> int:
    """The pid of a process that has ended and been reaped."""
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def test_a_second_runner_is_refused_naming_the_first(db: tuple[Path, str]) -> None:
    path, run = db
    with Store.open(path) as first, Store.open(path) as second:
        with first.run_lock(run) as held:
            assert (held.host, held.pid) == (socket.gethostname(), os.getpid())
            with pytest.raises(RunLocked) as refused:
                second.acquire_run(run)
            msg = str(refused.value)
            assert (
                f"run {run} is already being run by host {held.host} pid {os.getpid()} since {held.since_utc}"
                in msg
            )
            with pytest.raises(RunLocked):  # nor may it write to the run behind the lock
                second.append(run, "ShotFired", {"index": 1})
            first.append(run, "ShotFired", {"index": 1})  # the holder may
        lock = second.acquire_run(run)  # released: free for the next runner
        second.release_run(lock)
        assert second.run_lock_holder(run) is None
        assert [e.kind for e in second.entries(run)] == ["RunCreated", "ShotFired"]


def test_a_sealed_run_cannot_be_locked(db: tuple[Path, str]) -> None:
    path, run = db
    with Store.open(path) as store:
        store.set_run_status(run, "finished", "PASS")
        with pytest.raises(RecordRefused, match="is finished: it is sealed"):
            store.acquire_run(run)
        assert store.run_lock_holder(run) is None


def test_a_lock_left_by_a_dead_process_on_this_host_is_broken_and_recorded(db: tuple[Path, str]) -> None:
    path, run = db
    gone = dead_pid()
    plant(path, run, socket.gethostname(), gone, datetime.now(UTC))  # lease still running
    with Store.open(path) as store, store.run_lock(run) as held:
        assert store.run_lock_holder(run) == held
        (broken,) = store.entries(run, kinds=["RunLockBroken"])
        assert broken.payload["holder"]["pid"] == gone
        assert broken.payload["reason"] == f"process {gone} no longer runs on {socket.gethostname()}"
        assert broken.payload["taken_by"]["pid"] == os.getpid()
        assert "owner" not in broken.payload["holder"]  # the token stays a secret of its holder
        assert store.verify().ok


def test_a_live_lock_on_another_host_holds_until_its_lease_runs_out(db: tuple[Path, str]) -> None:
    path, run = db
    beat = datetime.now(UTC)
    plant(path, run, "bench-pc-2", 4242, beat, lease_s=30.0)
    early = Store.open(path, clock=lambda: beat + timedelta(seconds=29))
    with early, pytest.raises(RunLocked, match=r"host bench-pc-2 pid 4242 since .* its lease runs out at"):
        early.acquire_run(run)
    with Store.open(path, clock=lambda: beat + timedelta(seconds=31)) as late:
        late.acquire_run(run)
        (broken,) = late.entries(run, kinds=["RunLockBroken"])
        assert broken.payload["reason"].startswith("its lease expired at")
        assert broken.payload["holder"]["host"] == "bench-pc-2"


def test_the_heartbeat_keeps_the_lease_and_a_broken_holder_is_stopped(db: tuple[Path, str]) -> None:
    path, run = db
    with Store.open(path) as store, store.run_lock(run, lease_s=0.4) as held:
        deadline = time.monotonic() + 10
        while store.run_lock_holder(run).heartbeat_utc == held.heartbeat_utc:  # type: ignore[union-attr]
            assert time.monotonic() < deadline, "the heartbeat never renewed the lease"
            time.sleep(0.02)
    with Store.open(path) as holder:
        silent = holder.acquire_run(run, lease_s=1.0)  # taken, but no heartbeat: a hung runner
        later = datetime.fromisoformat(silent.heartbeat_utc) + timedelta(seconds=2)
        with Store.open(path, clock=lambda: later) as other:
            other.acquire_run(run)
        with pytest.raises(RunLocked):  # the hung runner wakes up: its writes are refused
            holder.append(run, "ShotFired", {"index": 1})


def test_lease_must_be_a_sensible_number_of_seconds(db: tuple[Path, str]) -> None:
    path, run = db
    with Store.open(path) as store:
        for bad in (0, -1, float("nan"), float("inf"), 1e300):
            with pytest.raises(RecordRefused, match="lease_s"):
                store.acquire_run(run, lease_s=bad)


def test_the_heartbeat_skips_a_busy_beat_and_ends_itself_when_the_lock_is_gone() -> None:
    answers: list[object] = [True, StoreError("database is locked"), True, False]
    calls: list[float] = []

    def renew() -> bool:
        calls.append(time.monotonic())
        answer = answers.pop(0)
        if isinstance(answer, Exception):
            raise answer
        return bool(answer)

    beat = Heartbeat(renew, "test-beat", interval_s=0.01)
    beat.start()
    beat.join(timeout=5.0)
    assert not beat.is_alive()  # ended on its own at the False, without stop()
    assert len(calls) == 4 and answers == []  # the StoreError beat was skipped, not fatal
    beat.stop()  # harmless after the end
