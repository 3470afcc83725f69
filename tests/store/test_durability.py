"""Durability and concurrency: SQLite settings, a writer killed with SIGKILL, readers during writes."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from rig.store import Store, StoreError, encode_bytes
from tests.store.conftest import populate

ROOT = Path(__file__).resolve().parents[2]

# The child appends until killed and prints each seq only after append() has returned.
_WRITER = """
import sys
from rig.store import Store, encode_bytes
store = Store.open(sys.argv[1])
store.register_bat("B-1", {})
run = store.create_run("bbcor", "B-1", {})
print("run", run, flush=True)
i = 0
while True:
    i += 1
    traffic = {"i": i, "data": encode_bytes(bytes(range(256)) * 8)}
    if i % 7:
        written = [store.append(run, "ShotMeasured", {"i": i})]
    else:
        written = store.append_many([(run, "Traffic", traffic), (run, "ShotMeasured", {"i": i})])
    for entry in written:
        print(entry.seq, flush=True)
"""


def test_wal_and_full_sync_are_set(store: Store) -> None:
    assert store.pragmas() == {
        "journal_mode": "wal",
        "synchronous": 2,
        "foreign_keys": 1,
        "busy_timeout": 5000,
    }
    store.append(None, "Note", {})
    db = sqlite3.connect(store.path)
    try:  # journal_mode=WAL is a property of the file, not just of our connection
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    finally:
        db.close()
    assert Path(f"{store.path}-wal").exists()


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")
@pytest.mark.usefixtures("cpu_load")
def test_every_returned_append_survives_sigkill(tmp_path: Path) -> None:
    path = tmp_path / "killed.db"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(path)], stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT
    )
    assert child.stdout is not None
    try:
        run = child.stdout.readline().split()[1]
        printed = [int(child.stdout.readline()) for _ in range(300)]
    finally:
        child.send_signal(signal.SIGKILL)  # mid-append, most likely
        rest, _ = child.communicate(timeout=10)
    assert child.returncode == -signal.SIGKILL
    printed += [int(line) for line in rest.split() if line.isdigit()]

    with Store.open(path, create=False) as store:
        report = store.verify()
        assert report.ok, report
        entries = store.entries(run)
        seqs = [e.seq for e in entries]
        assert set(printed) <= set(seqs)
        assert [e.chain_seq for e in entries] == list(range(1, len(entries) + 1))  # no holes after the kill
        assert [r.run_id for r in store.open_runs()] == [run]
        assert store.run(run).last_seq == seqs[-1]


def test_a_reader_sees_a_consistent_prefix_while_a_writer_appends(tmp_path: Path) -> None:
    path = tmp_path / "busy.db"
    with Store.open(path) as writer:
        populated = populate(writer)
        done, seen, errors = threading.Event(), [], []

        def read() -> None:
            with Store.open(path, create=False) as reader:
                while not done.is_set():
                    try:
                        entries = reader.entries()
                        assert [e.seq for e in entries] == list(range(1, len(entries) + 1))
                        report = reader.verify()
                        assert report.ok, report
                        seen.append(len(entries))
                    except (AssertionError, StoreError) as exc:
                        errors.append(exc)
                        return

        thread = threading.Thread(target=read)
        thread.start()
        try:
            # Keep writing until the reader has overlapped with the writer a few times.
            deadline = time.monotonic() + 10
            i = 0
            while (i < 300 or len(set(seen)) < 3) and time.monotonic() < deadline and not errors:
                writer.append(populated.run_b, "Traffic", {"i": i, "data": encode_bytes(b"\x02P?\r")})
                i += 1
        finally:
            done.set()
            thread.join(timeout=10)
        assert not errors, errors
        assert len(set(seen)) >= 3 and seen == sorted(seen)


def test_an_open_read_transaction_does_not_block_the_writer(tmp_path: Path) -> None:
    path = tmp_path / "wal.db"
    with Store.open(path, busy_timeout_s=0.2) as writer:
        writer.append(None, "Note", {"n": 0})
        reader = sqlite3.connect(path, isolation_level=None)
        try:
            reader.execute("BEGIN")
            assert reader.execute("SELECT count(*) FROM log").fetchone()[0] == 1
            writer.append(None, "Note", {"n": 1})  # would time out in rollback-journal mode
            assert reader.execute("SELECT count(*) FROM log").fetchone()[0] == 1  # its snapshot
            reader.execute("COMMIT")
            assert reader.execute("SELECT count(*) FROM log").fetchone()[0] == 2
        finally:
            reader.close()


def test_one_store_shared_by_threads_and_two_writers_keep_one_chain(tmp_path: Path) -> None:
    path = tmp_path / "shared.db"
    with Store.open(path) as shared, Store.open(path) as second:
        errors: list[BaseException] = []

        def work(store: Store, name: str) -> None:
            try:
                for i in range(100):
                    store.append(None, "Note", {"by": name, "i": i})
                    store.entries(after_seq=max(0, store.head().seq - 3))
            except BaseException as exc:  # surfaced below
                errors.append(exc)

        threads = [
            threading.Thread(target=work, args=(shared, "ui")),
            threading.Thread(target=work, args=(shared, "runner")),
            threading.Thread(target=work, args=(second, "other")),
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=20)
        assert not errors, errors
        report = shared.verify()
        assert report.ok and report.entries_checked == 300
