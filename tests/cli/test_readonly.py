"""A store on read-only media (issue 21, item 4): `rig runs`, `verify`, `report` and `export` read it;
a command that must write says the store is read-only, in one line, and changes nothing.

The folder is made read-only for the `rig` process the way a DVD or a write-protected share is:
as root (who may write any file) by a read-only bind mount in the child's own mount namespace;
otherwise by taking away the write permission of the folder and its files.
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import sqlite3
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.store import SCHEMA_VERSION, Store
from tests.cli.conftest import rig_env

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"
AS_ROOT = os.geteuid() == 0
# sh -c SCRIPT sh FOLDER COMMAND...: mount FOLDER read-only for this process alone, then run COMMAND
READ_ONLY_MOUNT = 'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" && shift && exec "$@"'


@functools.cache
def _can_mount() -> bool:
    probe = ["unshare", "--mount", "--propagation", "private", "sh", "-c", READ_ONLY_MOUNT, "sh", "/", "true"]
    try:
        return subprocess.run(probe, capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


@pytest.fixture
def folder(tmp_path: Path) -> Iterator[Path]:
    """An empty folder that `rig` will see read-only once `protect` is called."""
    if AS_ROOT and not _can_mount():
        pytest.skip("as root, read-only media need a private read-only mount (unshare, CAP_SYS_ADMIN)")
    path = tmp_path / "media"
    path.mkdir()
    yield path
    path.chmod(0o755)  # tmp_path's clean-up must be able to delete it


def protect(folder: Path) -> dict[str, str]:
    """Make `folder` and its files read-only for `rig` (see the module's docstring); their digests."""
    digests = {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in folder.iterdir()}
    if not AS_ROOT:
        for f in folder.iterdir():
            f.chmod(0o444)
        folder.chmod(0o555)
    return digests


def rig(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """`rig ARGS` in its own process, `folder` read-only for it."""
    command = [sys.executable, "-m", "rig.cli", *args]
    if AS_ROOT:
        unshare = ["unshare", "--mount", "--propagation", "private", "sh", "-c", READ_ONLY_MOUNT, "sh"]
        command = [*unshare, str(folder), *command]
    return subprocess.run(command, capture_output=True, text=True, cwd=ROOT, env=rig_env(), timeout=300)


def _unchanged(folder: Path, digests: dict[str, str]) -> None:
    assert {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in folder.iterdir()} == digests


def test_the_reading_commands_read_a_read_only_store(store_db: Path, folder: Path) -> None:
    shutil.copyfile(store_db, folder / "records.db")
    digests = protect(folder)
    db = str(folder / "records.db")
    for args in (
        ["runs"],
        ["runs", "--json"],
        ["verify"],
        ["report", "last", "--format", "json"],
        ["export", "--view", "shots", "--output", "-"],
    ):
        done = rig(folder, *args, "--db", db)
        assert done.returncode == 0, (args, done.stderr)
        assert done.stdout.strip(), args
    _unchanged(folder, digests)


def test_a_write_to_a_read_only_store_says_so(store_db: Path, folder: Path) -> None:
    shutil.copyfile(store_db, folder / "records.db")
    digests = protect(folder)
    bat = str(ROOT / "protocols" / "examples" / "sample-bat.toml")
    done = rig(
        folder,
        "certify",
        "--procedure",
        "bbcor",
        "--bat",
        bat,
        "--sim",
        "ideal",
        "--db",
        str(folder / "records.db"),
    )
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "read-only" in done.stderr, done.stderr
    assert "not a SQLite database" not in done.stderr
    _unchanged(folder, digests)


def test_entries_still_in_the_wal_without_its_index_are_named(tmp_path: Path, folder: Path) -> None:
    """A live store copied without its -shm: the -wal's entries cannot be read here, nor dropped."""
    with Store.open(tmp_path / "live.db") as store:
        store.append(None, "Note", {"text": "in the file"})
        store._conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        store.append(None, "Note", {"text": "only in the wal"})
        shutil.copyfile(tmp_path / "live.db", folder / "live.db")
        shutil.copyfile(tmp_path / "live.db-wal", folder / "live.db-wal")
    digests = protect(folder)
    done = rig(folder, "runs", "--db", str(folder / "live.db"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "read-only" in done.stderr and "live.db-wal" in done.stderr
    _unchanged(folder, digests)


def test_an_old_store_that_needs_upgrading_says_so(folder: Path) -> None:
    shutil.copyfile(FIXTURES / "log-v1.db", folder / "old.db")
    with sqlite3.connect(f"file:{folder / 'old.db'}?mode=ro", uri=True) as db:
        assert db.execute("SELECT max(version) FROM schema_version").fetchone()[0] < SCHEMA_VERSION
    digests = protect(folder)
    done = rig(folder, "verify", "--db", str(folder / "old.db"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "read-only" in done.stderr and "upgrade" in done.stderr
    _unchanged(folder, digests)
