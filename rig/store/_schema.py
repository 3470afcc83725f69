"""The file: opening it safely, telling ours from a foreign one, the schema and its migrations."""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

from rig.core.errors import StoreFileError
from rig.store import _readonly
from rig.store._views import SQLITE_VIEWS

# Written into the SQLite header so that a rig store is recognisable without reading tables.
APPLICATION_ID = 0x52494753  # "RIGS"

# Version n is reached by applying MIGRATIONS[n - 1] to a version n - 1 file, in one transaction.
# Append new versions; never edit a released one (files in the field were made by it).
MIGRATIONS: tuple[tuple[str, ...], ...] = (
    (
        "CREATE TABLE schema_version (version INTEGER PRIMARY KEY, applied_utc TEXT NOT NULL)",
        """CREATE TABLE log (
            seq INTEGER PRIMARY KEY,
            run_id TEXT,
            kind TEXT NOT NULL,
            payload TEXT NOT NULL,
            t_utc TEXT NOT NULL,
            prev_hash TEXT NOT NULL,
            hash TEXT NOT NULL UNIQUE)""",
        "CREATE INDEX log_by_run ON log (run_id, seq)",
        "CREATE INDEX log_by_kind ON log (kind, seq)",
        # Refuse edits through SQL by mistake; deliberate tampering (dropping these) is what
        # the hash chain is for.
        """CREATE TRIGGER log_no_update BEFORE UPDATE ON log
            BEGIN SELECT RAISE(ABORT, 'the log is append-only'); END""",
        """CREATE TRIGGER log_no_delete BEFORE DELETE ON log
            BEGIN SELECT RAISE(ABORT, 'the log is append-only'); END""",
        "CREATE TABLE bats (id TEXT PRIMARY KEY, spec TEXT NOT NULL)",
        """CREATE TABLE runs (
            run_id TEXT PRIMARY KEY,
            procedure TEXT NOT NULL,
            bat_id TEXT NOT NULL REFERENCES bats (id),
            started_utc TEXT NOT NULL,
            status TEXT NOT NULL CHECK (status IN ('running', 'finished', 'aborted')),
            verdict TEXT,
            last_seq INTEGER NOT NULL)""",
        "CREATE INDEX runs_by_status ON runs (status, started_utc)",
    ),
    (
        # Version 2: one runner per run. A row here is the run's lock: who holds it and until
        # when its lease runs. Not part of the record (never hashed, never derived from the log).
        """CREATE TABLE run_locks (
            run_id TEXT PRIMARY KEY,
            owner TEXT NOT NULL,
            host TEXT NOT NULL,
            pid INTEGER NOT NULL,
            since_utc TEXT NOT NULL,
            heartbeat_utc TEXT NOT NULL,
            lease_s REAL NOT NULL CHECK (lease_s > 0))""",
    ),
    (
        # Version 3: chain format 2, one hash chain per run plus the lab chain (entries of no run,
        # and each run's anchors), so that several rigs append to one database without waiting
        # for each other and a run's records can be copied whole to another store (rig sync).
        # A file that already holds entries keeps format 1 (one chain through every entry).
        "ALTER TABLE log ADD COLUMN chain TEXT",
        "ALTER TABLE log ADD COLUMN chain_seq INTEGER",
        "CREATE UNIQUE INDEX log_by_chain ON log (chain, chain_seq)",
        "CREATE TABLE store_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    ),
    # Version 4: the analysts' views `shots` and `runs_summary` (rig/store/_views.py). Schema,
    # not data: nothing is hashed. Once released, change a view by a new version (DROP, CREATE).
    SQLITE_VIEWS,
)
SCHEMA_VERSION = len(MIGRATIONS)
APPEND_ONLY_TRIGGERS = ("log_no_update", "log_no_delete")


def connect(path: Path, *, create: bool, busy_timeout_s: float, readonly: bool = False) -> sqlite3.Connection:
    """An open, migrated connection in WAL mode with synchronous=FULL and foreign keys on.

    `readonly`: open the file for reading only (a store on read-only media reads; see _readonly).
    """
    if not (create and not readonly) and not path.exists():
        raise StoreFileError(f"{path}: no such store")
    if path.is_dir():
        raise StoreFileError(f"{path}: is a directory, not a store file")
    if not path.parent.is_dir():
        raise StoreFileError(f"{path}: the folder {path.parent} does not exist")
    if readonly:
        conn = _read_only(path, busy_timeout_s)
        if conn is not None:
            return conn
    why = _readonly.cannot_write(path)  # a store on read-only media: say so, not "not a database"
    if why is not None:
        raise StoreFileError(f"{path}: read-only ({why}); a store that is written must be on writable media")
    try:
        # isolation_level=None: we issue BEGIN/COMMIT ourselves, so every transaction is explicit.
        # check_same_thread=False: the Store serialises use with its own lock.
        conn = sqlite3.connect(path, timeout=busy_timeout_s, isolation_level=None, check_same_thread=False)
    except sqlite3.Error as exc:
        raise StoreFileError(f"{path}: cannot open: {exc}") from None
    with _closed_on_error(conn, path):
        fresh = _identify(conn, path)
        _configure(conn, path, busy_timeout_s)
        _migrate(conn, path, fresh)
    return conn


@contextlib.contextmanager
def _closed_on_error(conn: sqlite3.Connection, path: Path) -> Iterator[None]:
    """Close `conn` if the block fails; an SQLite error becomes one line naming the store."""
    try:
        yield
    except sqlite3.Error as exc:
        conn.close()
        raise StoreFileError(f"{path}: not a usable store: {exc}") from None
    except BaseException:
        conn.close()
        raise


def _read_only(path: Path, busy_timeout_s: float) -> sqlite3.Connection | None:
    """A connection that only reads; None if the store must be upgraded first and can be (a writable
    file of an older schema, or an empty one: opened for writing, as before)."""
    conn = _readonly.connect(path, busy_timeout_s)
    with _closed_on_error(conn, path):
        fresh = _identify(conn, path)
        version = 0 if fresh else _current_version(conn, path, fresh)
        if version != SCHEMA_VERSION and _readonly.cannot_write(path) is None:
            conn.close()
            return None
        _readonly.check_current(path, version, SCHEMA_VERSION)
        conn.execute(f"PRAGMA busy_timeout={int(busy_timeout_s * 1000)}")
    return conn


def _identify(conn: sqlite3.Connection, path: Path) -> bool:
    """True for an empty file to initialise; raise for a foreign one before changing it."""
    try:
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        n_objects = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
    except sqlite3.DatabaseError as exc:
        raise StoreFileError(f"{path}: not a SQLite database ({exc})") from None
    if app_id == APPLICATION_ID:
        return False
    if app_id == 0 and n_objects == 0:
        return True
    raise StoreFileError(
        f"{path}: a SQLite database but not a rig store "
        f"(application_id {app_id:#x}, {n_objects} schema objects); refusing to touch it"
    )


def _configure(conn: sqlite3.Connection, path: Path, busy_timeout_s: float) -> None:
    mode = conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
    if str(mode).lower() != "wal":
        raise StoreFileError(f"{path}: cannot switch to WAL mode (journal_mode is {mode})")
    # FULL in WAL mode syncs the WAL at every commit: a returned append survives power loss too.
    conn.execute("PRAGMA synchronous=FULL")
    conn.execute("PRAGMA foreign_keys=ON")
    conn.execute(f"PRAGMA busy_timeout={int(busy_timeout_s * 1000)}")


def _migrate(conn: sqlite3.Connection, path: Path, fresh: bool) -> None:
    # The common case, an up-to-date file, needs no write lock (readers must not wait for one).
    if not fresh and _current_version(conn, path, fresh) == SCHEMA_VERSION:
        return
    # IMMEDIATE: two processes opening a new file at once must not both initialise it.
    conn.execute("BEGIN IMMEDIATE")
    try:
        version = _current_version(conn, path, fresh)
        if version > SCHEMA_VERSION:
            raise StoreFileError(
                f"{path}: written by newer software (schema {version}; this one knows up to {SCHEMA_VERSION})"
            )
        for target in range(version + 1, SCHEMA_VERSION + 1):
            for statement in MIGRATIONS[target - 1]:
                conn.execute(statement)
            conn.execute(
                "INSERT INTO schema_version (version, applied_utc) VALUES (?, ?)",
                (target, datetime.now(UTC).isoformat(timespec="seconds")),
            )
        _settle_format(conn)
        conn.execute(f"PRAGMA application_id={APPLICATION_ID}")
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:  # a full disk may have rolled it back already
            conn.execute("ROLLBACK")
        raise


def _current_version(conn: sqlite3.Connection, path: Path, fresh: bool) -> int:
    has_table = conn.execute(
        "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'schema_version'"
    ).fetchone()[0]
    if not has_table:
        # Another process may have initialised the file between _identify and BEGIN IMMEDIATE.
        if fresh:
            return 0
        raise StoreFileError(f"{path}: marked as a rig store but has no schema_version table")
    version = conn.execute("SELECT max(version) FROM schema_version").fetchone()[0]
    if version is None:
        raise StoreFileError(f"{path}: the schema_version table is empty")
    return int(version)


CHAIN_FORMATS = (1, 2)


def _settle_format(conn: sqlite3.Connection) -> None:
    """Record the file's chain format once: 2 for a file with no entries yet, else 1."""
    if not _has_meta(conn) or conn.execute("SELECT 1 FROM store_meta WHERE key = 'chain_format'").fetchone():
        return
    empty = conn.execute("SELECT count(*) FROM log").fetchone()[0] == 0
    conn.execute("INSERT INTO store_meta (key, value) VALUES ('chain_format', ?)", ("2" if empty else "1",))


def chain_format(conn: sqlite3.Connection, path: Path | str) -> int:
    """The file's chain format (1: one chain through the file; 2: a chain per run and the lab's)."""
    if not _has_meta(conn):
        return 1  # a file of a schema before 3: one chain
    row = conn.execute("SELECT value FROM store_meta WHERE key = 'chain_format'").fetchone()
    if row is None or row[0] not in ("1", "2"):
        raise StoreFileError(f"{path}: no valid chain format recorded (store_meta damaged?)")
    return int(row[0])


def set_chain_format(conn: sqlite3.Connection, path: Path, version: int) -> None:
    """Choose the chain format of a store with no entries yet (tests of format 1, old tools)."""
    if version not in CHAIN_FORMATS:
        raise StoreFileError(f"{path}: chain format {version!r}: known formats are 1 and 2")
    if chain_format(conn, path) == version:
        return
    if conn.execute("SELECT count(*) FROM log").fetchone()[0]:
        raise StoreFileError(f"{path}: holds entries; its chain format cannot change")
    conn.execute("UPDATE store_meta SET value = ? WHERE key = 'chain_format'", (str(version),))


def _has_meta(conn: sqlite3.Connection) -> bool:
    query = "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = 'store_meta'"
    return bool(conn.execute(query).fetchone()[0])
