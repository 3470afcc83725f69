"""Opening files: bad, foreign, missing or too-new files are refused by name; migrations apply."""

from __future__ import annotations

import re
import sqlite3
from pathlib import Path

import pytest

from rig.core.errors import RigError
from rig.store import SCHEMA_VERSION, Store, StoreError, StoreFileError, _schema


def test_garbage_file_is_refused_by_name(tmp_path: Path) -> None:
    path = tmp_path / "notes.txt"
    path.write_bytes(b"shot 1: 61.2 m/s\n" * 100)
    with pytest.raises(StoreFileError, match=re.escape(f"{path}: not a SQLite database")) as info:
        Store.open(path)
    assert isinstance(info.value, StoreError) and isinstance(info.value, RigError)
    assert path.read_bytes() == b"shot 1: 61.2 m/s\n" * 100


def test_foreign_sqlite_file_is_refused_untouched(tmp_path: Path) -> None:
    path = tmp_path / "other.db"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE log (x)")
    db.commit()
    db.close()
    before = path.read_bytes()
    with pytest.raises(StoreFileError, match=re.escape(f"{path}: a SQLite database but not a rig store")):
        Store.open(path)
    assert path.read_bytes() == before  # not even switched to WAL


@pytest.mark.parametrize("case", ["missing", "folder", "no-parent"])
def test_missing_or_wrong_paths(tmp_path: Path, case: str) -> None:
    path = {"missing": tmp_path / "none.db", "folder": tmp_path, "no-parent": tmp_path / "a" / "b.db"}[case]
    with pytest.raises(StoreFileError, match=re.escape(str(path))):
        Store.open(path, create=case != "missing")
    assert case != "missing" or not path.exists()


def test_reopening_keeps_the_schema_and_the_entries(tmp_path: Path) -> None:
    path = tmp_path / "rig.db"
    with Store.open(path) as store:
        store.append(None, "Note", {"n": 1})
    with Store.open(path, create=False) as store:
        assert [e.payload for e in store.entries()] == [{"n": 1}]
    db = sqlite3.connect(path)
    try:
        versions = db.execute("SELECT version FROM schema_version ORDER BY version").fetchall()
        assert versions == [(v,) for v in range(1, SCHEMA_VERSION + 1)]
        assert db.execute("PRAGMA application_id").fetchone()[0] == _schema.APPLICATION_ID
    finally:
        db.close()


def test_a_file_from_newer_software_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "rig.db"
    Store.open(path).close()
    db = sqlite3.connect(path)
    db.execute("INSERT INTO schema_version VALUES (?, 'later')", (SCHEMA_VERSION + 1,))
    db.commit()
    db.close()
    with pytest.raises(StoreFileError, match=f"schema {SCHEMA_VERSION + 1}; this one knows up to"):
        Store.open(path)


def test_an_older_file_is_migrated_in_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "rig.db"
    with Store.open(path) as store:
        store.append(None, "Note", {"n": 1})
    later = ("CREATE TABLE later_table (seq INTEGER PRIMARY KEY REFERENCES log (seq))",)
    monkeypatch.setattr(_schema, "MIGRATIONS", (*_schema.MIGRATIONS, later))
    monkeypatch.setattr(_schema, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    with Store.open(path) as store:
        assert store.verify().ok
    db = sqlite3.connect(path)
    try:
        versions = [v for (v,) in db.execute("SELECT version FROM schema_version ORDER BY version")]
        assert versions == list(range(1, SCHEMA_VERSION + 2))
        assert db.execute("SELECT count(*) FROM later_table").fetchone()[0] == 0
    finally:
        db.close()


def test_a_failed_migration_leaves_the_file_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "rig.db"
    Store.open(path).close()
    bad = ("CREATE TABLE extra (x)", "CREATE TABLE log (y)")  # second statement fails
    monkeypatch.setattr(_schema, "MIGRATIONS", (*_schema.MIGRATIONS, bad))
    monkeypatch.setattr(_schema, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    with pytest.raises(StoreFileError, match="already exists"):
        Store.open(path)
    monkeypatch.undo()
    with Store.open(path) as store:
        assert store.verify().ok
    db = sqlite3.connect(path)
    try:
        assert db.execute("SELECT count(*) FROM sqlite_master WHERE name = 'extra'").fetchone()[0] == 0
    finally:
        db.close()


def test_a_store_opened_read_only_refuses_writes_and_is_not_changed(tmp_path: Path) -> None:
    path = tmp_path / "rig.db"
    with Store.open(path) as store:
        store.append(None, "Note", {"n": 1})
    before = path.read_bytes()
    with Store.open(path, readonly=True) as store:
        assert [e.payload for e in store.entries()] == [{"n": 1}] and store.verify().ok
        with pytest.raises(StoreError, match="opened read-only"):
            store.append(None, "Note", {"n": 2})
    assert path.read_bytes() == before
    with pytest.raises(StoreFileError, match="no such store"):
        Store.open(tmp_path / "none.db", readonly=True)
    assert not (tmp_path / "none.db").exists()
