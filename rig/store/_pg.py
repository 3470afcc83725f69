"""The store on PostgreSQL: a lab's database that several rigs append to (psycopg 3).

The same log, the same chain format 2 (a chain per run and the lab chain) and the same tables as
the SQLite file; `PgConn` gives the store's code the sqlite3-like calls it uses (`?` parameters,
explicit BEGIN/COMMIT). Appends to different runs do not wait for each other: an append locks only
its own chain (a transaction-scoped advisory lock), and the global `seq` comes from an identity
column (it orders entries; it may skip numbers, which verification allows in format 2).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from datetime import UTC, datetime
from typing import Any

from rig.core.errors import StoreFileError
from rig.store._views import POSTGRES_VIEWS

SCHEMA_VERSION_PG = 4  # the SQLite schema version whose tables and views this one matches
_MARK = "rig-store"  # the database comment that says a database is a rig store

DDL: tuple[str, ...] = (
    "CREATE TABLE schema_version (version INTEGER PRIMARY KEY, applied_utc TEXT NOT NULL)",
    """CREATE TABLE log (
        seq BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
        run_id TEXT,
        kind TEXT NOT NULL,
        payload TEXT NOT NULL,
        t_utc TEXT NOT NULL,
        prev_hash TEXT NOT NULL,
        hash TEXT NOT NULL UNIQUE,
        chain TEXT NOT NULL,
        chain_seq BIGINT NOT NULL,
        UNIQUE (chain, chain_seq))""",
    "CREATE INDEX log_by_run ON log (run_id, seq)",
    "CREATE INDEX log_by_kind ON log (kind, seq)",
    """CREATE FUNCTION log_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
        BEGIN RAISE EXCEPTION 'the log is append-only'; END $$""",
    """CREATE TRIGGER log_no_update BEFORE UPDATE ON log
        FOR EACH ROW EXECUTE FUNCTION log_append_only()""",
    """CREATE TRIGGER log_no_delete BEFORE DELETE ON log
        FOR EACH ROW EXECUTE FUNCTION log_append_only()""",
    "CREATE TABLE bats (id TEXT PRIMARY KEY, spec TEXT NOT NULL)",
    """CREATE TABLE runs (
        run_id TEXT PRIMARY KEY,
        procedure TEXT NOT NULL,
        bat_id TEXT NOT NULL REFERENCES bats (id),
        started_utc TEXT NOT NULL,
        status TEXT NOT NULL CHECK (status IN ('running', 'finished', 'aborted')),
        verdict TEXT,
        last_seq BIGINT NOT NULL)""",
    "CREATE INDEX runs_by_status ON runs (status, started_utc)",
    """CREATE TABLE run_locks (
        run_id TEXT PRIMARY KEY,
        owner TEXT NOT NULL,
        host TEXT NOT NULL,
        pid INTEGER NOT NULL,
        since_utc TEXT NOT NULL,
        heartbeat_utc TEXT NOT NULL,
        lease_s DOUBLE PRECISION NOT NULL CHECK (lease_s > 0))""",
    "CREATE TABLE store_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
    "INSERT INTO store_meta (key, value) VALUES ('chain_format', '2')",
    *POSTGRES_VIEWS,
)
APPEND_ONLY_TRIGGERS_PG = ("log_no_update", "log_no_delete")

_QMARK = re.compile(r"\?")


class PgCursor:
    """The part of a DB-API cursor the store reads: rows, one row, rowcount, lastrowid."""

    def __init__(self, cur: Any) -> None:
        self._cur = cur
        self.rowcount = cur.rowcount

    def fetchone(self) -> Any:
        """The next row or None."""
        return self._cur.fetchone() if self._cur.description else None

    def fetchall(self) -> list[Any]:
        """The remaining rows."""
        return list(self._cur.fetchall()) if self._cur.description else []

    def __iter__(self) -> Any:
        return iter(self.fetchall())


class PgConn:
    """A psycopg connection in autocommit mode that speaks the store's sqlite3-style SQL."""

    engine = "postgresql"

    def __init__(self, conn: Any, url: str) -> None:
        self._conn = conn
        self.url = url

    def execute(self, sql: str, params: Sequence[Any] = ()) -> PgCursor:
        """Run one statement; `?` marks parameters, as in sqlite3."""
        text = _QMARK.sub("%s", sql.replace("%", "%%")) if params else sql
        if sql.strip().upper() == "BEGIN IMMEDIATE":
            text = "BEGIN"  # PostgreSQL locks per chain (lock_chain), not the whole database
        return PgCursor(self._conn.execute(text, tuple(params) if params else None))

    def executemany(self, sql: str, rows: Iterable[Sequence[Any]]) -> None:
        """Run one statement for each row."""
        with self._conn.cursor() as cur:
            cur.executemany(_QMARK.sub("%s", sql.replace("%", "%%")), [tuple(r) for r in rows])

    @property
    def in_transaction(self) -> bool:
        """Whether a transaction is open (BEGIN without COMMIT or ROLLBACK yet)."""
        from psycopg import pq

        return bool(self._conn.info.transaction_status != pq.TransactionStatus.IDLE)

    def lock_chain(self, chain: str) -> None:
        """Hold the chain's append lock until the transaction ends."""
        self._conn.execute("SELECT pg_advisory_xact_lock(hashtextextended(%s, 0))", (chain,))

    def close(self) -> None:
        """Close the connection."""
        self._conn.close()


def safe_url(url: str) -> str:
    """The URL without its password, to name the database in messages."""
    return re.sub(r"//([^:/@]+):[^@/]*@", r"//\1:***@", url)


def connect_pg(url: str, *, create: bool, timeout_s: float) -> PgConn:
    """A connection to a lab database, its schema made (an empty database) or checked."""
    try:
        import psycopg
    except ImportError:  # pragma: no cover - a dependency of the package
        raise StoreFileError("PostgreSQL needs the psycopg package (pip install 'psycopg[binary]')") from None
    shown = safe_url(url)
    try:
        raw = psycopg.connect(url, autocommit=True, connect_timeout=max(1, round(timeout_s)))
    except psycopg.OperationalError as exc:
        raise StoreFileError(f"{shown}: cannot connect: {_first_line(exc)}") from None
    except psycopg.ProgrammingError as exc:
        raise StoreFileError(f"{shown}: not a usable PostgreSQL URL: {_first_line(exc)}") from None
    conn = PgConn(raw, url)
    try:
        _migrate(conn, shown, create)
    except psycopg.Error as exc:
        conn.close()
        raise StoreFileError(f"{shown}: not a usable store: {_first_line(exc)}") from None
    except BaseException:
        conn.close()
        raise
    return conn


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def _tables(conn: PgConn) -> set[str]:
    rows = conn.execute("SELECT tablename FROM pg_tables WHERE schemaname = current_schema()").fetchall()
    return {r[0] for r in rows}


def _migrate(conn: PgConn, shown: str, create: bool) -> None:
    conn.execute("BEGIN")
    try:
        # one process initialises a new database; the others wait here, then find it made
        conn.execute("SELECT pg_advisory_xact_lock(hashtextextended('rig-store-schema', 0))")
        tables = _tables(conn)
        if not tables:
            if not create:
                raise StoreFileError(f"{shown}: an empty database, not a store (create it first)")
            for statement in DDL:
                conn.execute(statement)
            conn.execute(
                "INSERT INTO schema_version (version, applied_utc) VALUES (?, ?)",
                (SCHEMA_VERSION_PG, datetime.now(UTC).isoformat(timespec="seconds")),
            )
            conn.execute(f"COMMENT ON TABLE log IS '{_MARK}'")
        elif "log" not in tables or "schema_version" not in tables or not _marked(conn):
            raise StoreFileError(
                f"{shown}: a database with other tables ({', '.join(sorted(tables)[:5])}), not a rig store; "
                "refusing to touch it"
            )
        else:
            version = conn.execute("SELECT max(version) FROM schema_version").fetchone()[0]
            if version is None or version > SCHEMA_VERSION_PG:
                raise StoreFileError(
                    f"{shown}: written by newer software (schema {version}; this one knows up to "
                    f"{SCHEMA_VERSION_PG})"
                )
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        raise


def _marked(conn: PgConn) -> bool:
    row = conn.execute("SELECT obj_description('log'::regclass, 'pg_class')").fetchone()
    return row is not None and row[0] == _MARK


URL_SCHEMES = ("postgresql://", "postgres://")


def is_url(location: object) -> bool:
    """Whether a store location is a database URL rather than a file path."""
    return isinstance(location, str) and (location.startswith(URL_SCHEMES) or location.startswith("sqlite:"))


def is_db_error(exc: BaseException) -> bool:
    """Whether `exc` is a PostgreSQL (psycopg) error."""
    try:
        import psycopg
    except ImportError:  # pragma: no cover
        return False
    return isinstance(exc, psycopg.Error)


def db_error_text(exc: BaseException) -> str:
    """One line for a database error: its first line, a lost connection said plainly."""
    import psycopg

    if isinstance(exc, psycopg.OperationalError):
        return f"the database connection failed ({_first_line(exc)}); the run is resumable once it is back"
    return _first_line(exc)
