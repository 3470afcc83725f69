"""A store whose file vanishes or is damaged while it is open (issue 21, items 1 and 2): the next write
is refused, naming what happened, and a damaged store is refused before anything is recorded."""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

import pytest

from rig.store import Store, StoreError
from tests.store.conftest import raw


def _files(path: Path) -> list[Path]:
    return [path, path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")]


def _open_with_a_run(path: Path) -> tuple[Store, str]:
    store = Store.open(path)
    store.register_bat("B-1", {"model": "X33"})
    run = store.create_run("bbcor", "B-1", {})
    store.append(run, "ShotMeasured", {"shot": 0})
    return store, run


def test_the_files_deleted_under_an_open_store_refuse_the_next_write(tmp_path: Path) -> None:
    store, run = _open_with_a_run(tmp_path / "d.db")
    with store:
        for f in _files(tmp_path / "d.db"):
            f.unlink()
        with pytest.raises(StoreError, match=r"d\.db is gone"):
            store.append(run, "ShotMeasured", {"shot": 1})


@pytest.mark.parametrize("which", ["", "-wal", "-shm"])
def test_any_of_its_files_replaced_refuses_the_next_write(tmp_path: Path, which: str) -> None:
    path = tmp_path / "d.db"
    store, run = _open_with_a_run(path)
    with store:
        target = path.with_name(path.name + which)
        data = target.read_bytes()
        target.unlink()
        target.write_bytes(data)  # the same bytes, another file: not the one this store writes
        with pytest.raises(StoreError, match=f"d.db{which} was replaced"):
            store.append(run, "ShotMeasured", {"shot": 1})


def test_a_truncated_file_refuses_the_next_write(tmp_path: Path) -> None:
    path = tmp_path / "d.db"
    store, run = _open_with_a_run(path)
    with store:
        store._conn.execute("PRAGMA wal_checkpoint(FULL)")  # the entries are in the file itself now
        store.append(run, "ShotMeasured", {"shot": 1})
        os.truncate(path, 0)
        with pytest.raises(StoreError, match=r"d\.db was truncated"):
            store.append(run, "ShotMeasured", {"shot": 2})


def _damage(path: Path) -> None:
    """Zero the header of a leaf page of the log in the middle of the file (a bad sector)."""
    with sqlite3.connect(path) as db:
        db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        pages = [
            n for (n,) in db.execute("SELECT pageno FROM dbstat WHERE name = 'log' AND pagetype = 'leaf'")
        ]
        size = db.execute("PRAGMA page_size").fetchone()[0]
    with path.open("r+b") as f:
        f.seek((pages[len(pages) // 2] - 1) * size)
        f.write(b"\0" * 16)


def test_a_damaged_file_fails_the_integrity_check(tmp_path: Path) -> None:
    path = tmp_path / "d.db"
    store, run = _open_with_a_run(path)
    for i in range(1, 400):
        store.append(run, "ShotMeasured", {"shot": i, "pad": "x" * 200})
    store.check_integrity(run)  # a sound store passes
    store.close()
    _damage(path)
    with Store.open(path) as store, pytest.raises(StoreError, match=r"d\.db: damaged: .*rig verify"):
        store.check_integrity()


@pytest.mark.parametrize("fmt", [1, 2])
def test_a_broken_run_chain_fails_the_integrity_check(tmp_path: Path, fmt: int) -> None:
    path = tmp_path / "d.db"
    with Store.open(path, chain_format=fmt) as store:
        store.register_bat("B-1", {"model": "X33"})
        run = store.create_run("bbcor", "B-1", {})
        shots = [store.append(run, "ShotMeasured", {"shot": i}) for i in range(3)]
        store.append(None, "Note", {"text": "coffee"})
        store.check_integrity(run)
    with raw(path) as db:
        db.execute("UPDATE log SET payload = ? WHERE seq = ?", ('{"shot":9}', shots[1].seq))
    with Store.open(path) as store:
        store.check_integrity()  # the file is sound, and the chain's head too
        with pytest.raises(StoreError, match=f"run {run}.*hash mismatch.*rig verify"):
            store.check_integrity(run)
