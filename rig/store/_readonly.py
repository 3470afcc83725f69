"""Stores on read-only media (a DVD, a write-protected share, a file the user may only read):
reading them without writing anything, and saying so when a write is needed.

A store is a SQLite file in WAL mode; even a reader needs NAME-shm beside it, which SQLite cannot
make on read-only media. There the file is read as it is (SQLite's `immutable`), unless NAME-wal
holds entries not yet in the file, which only NAME-shm could index: those are never silently left
out, the reader is told to copy the files to writable media.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from rig.core.errors import StoreFileError


def cannot_write(path: Path) -> str | None:
    """Why the store at `path` (or a new one there) cannot be written, or None if it can."""
    folder = path.parent
    try:
        if os.statvfs(folder).f_flag & os.ST_RDONLY:
            return "its file system is mounted read-only"
    except OSError:
        pass
    if path.exists() and not os.access(path, os.W_OK):
        return "the file is not writable"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"its folder is not writable (SQLite keeps {path.name}-wal and {path.name}-shm there)"
    return None


def connect(path: Path, busy_timeout_s: float) -> sqlite3.Connection:
    """A connection that never writes to the store (check it is ours before use)."""
    uri = f"{path.resolve().as_uri()}?mode=ro"
    conn = _open(uri, path, busy_timeout_s)
    try:
        conn.execute("PRAGMA application_id").fetchone()  # SQLite opens the file (and NAME-shm) here
    except sqlite3.DatabaseError as exc:
        why = cannot_write(path)
        if getattr(exc, "sqlite_errorname", "") != "SQLITE_CANTOPEN" or why is None:
            return conn  # not a media matter: identifying the file names what is wrong
        conn.close()
        wal = path.with_name(f"{path.name}-wal")
        if wal.exists() and wal.stat().st_size > 0:
            raise StoreFileError(
                f"{path}: read-only ({why}), and {wal.name} holds entries not yet in the file that "
                f"only {path.name}-shm (missing) can index: copy {path.name} and {wal.name} to writable "
                "media and read them there"
            ) from None
        return _open(f"{uri}&immutable=1", path, busy_timeout_s)  # nothing beside it: the file is all
    return conn


def check_current(path: Path, version: int, current: int) -> None:
    """Refuse a store of an older schema that cannot be upgraded here (upgrading writes)."""
    if version == current:
        return
    why = cannot_write(path) or "opened for reading only"
    raise StoreFileError(
        f"{path}: read-only ({why}), and written by older software (schema {version}, now {current}): "
        "copy it to writable media, where opening it will upgrade it, and read it there"
    )


def _open(uri: str, path: Path, busy_timeout_s: float) -> sqlite3.Connection:
    try:
        return sqlite3.connect(
            uri, uri=True, timeout=busy_timeout_s, isolation_level=None, check_same_thread=False
        )
    except sqlite3.Error as exc:
        raise StoreFileError(f"{path}: cannot open: {exc}") from None
