"""The Store: an append-only hash-chained log and the tables derived from it, in one SQLite file
or a lab's PostgreSQL database.

Why one module of ~560 lines: every write to the record goes through this class, in one
transaction on one connection under one lock: appends on both engines and both chain formats,
the run lock that refuses a second runner, the seal and its lab-chain anchor, and the verbatim
import of `rig sync`. Their invariants (what a transaction holds, which chain is locked, when a
run is sealed) are read together; the parts that stand alone live beside it (_chains, _verify,
_lock, _pg, _sync, _views, _signed).
"""

from __future__ import annotations

import math
import os
import sqlite3
import threading
import uuid
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any, Self

from rig.core.errors import RecordRefused, StoreError, StoreFileError, UnknownRecord
from rig.store import _derive, _guard, _integrity, _lock, _lots, _signed, _sync, _verify, _views
from rig.store._codec import GENESIS_HASH, check_kind, check_payload, decode_payload, entry_hash
from rig.store._pg import connect_pg, db_error_text, is_db_error, is_url, safe_url
from rig.store._records import (
    BALL_LAW_RECORDED,
    BALL_LOT_REGISTERED,
    BAT_REGISTERED,
    CLOSED_STATUSES,
    LAB_CHAIN,
    RESERVED_KINDS,
    RUN_CREATED,
    RUN_LOCK_BROKEN,
    RUN_OPENED,
    RUN_SEALED,
    RUN_STATUS_CHANGED,
    RUN_SYNCED,
    Anchor,
    LogEntry,
    RunSummary,
    VerifyReport,
)
from rig.store._rows import ENTRY_COLUMNS, check_id, entry_from_row, known_ids
from rig.store._schema import chain_format, connect, set_chain_format

Clock = Callable[[], datetime]
EntrySpec = tuple[str | None, str, dict[str, Any]]  # (run_id, kind, payload) for append_many

_RUN_COLUMNS = ", ".join(_derive.RUN_COLUMNS)
_CLOSED_STATUSES = CLOSED_STATUSES
DEFAULT_LEASE_S = 30.0  # a killed runner on another machine blocks its run this long at most


def _utc_now() -> datetime:
    return datetime.now(UTC)


class Store:
    """Run records in one SQLite file (WAL). Thread-safe: one connection behind a lock.

    Every write is one transaction that appends to the log and updates the tables; when a
    write method returns, its entries are on disk.
    """

    def __init__(self, conn: Any, path: Path | str, clock: Clock) -> None:
        """Use `Store.open`."""
        self._conn: Any = conn  # sqlite3.Connection, or a PgConn for a PostgreSQL URL
        self.engine = getattr(conn, "engine", "sqlite")
        self.chain_format = chain_format(conn, path) if self.engine == "sqlite" else 2
        self._path = path  # a Path, or the URL without its password
        self._clock = clock
        self._lock = threading.RLock()
        self._held: dict[str, str] = {}  # run_id -> owner token of the run locks this Store holds
        self.readonly = False  # opened to read only (Store.open(readonly=True)): every write refused
        self._guard: _guard.FileGuard | None = None  # a SQLite writer's files (rig.store._guard)

    @classmethod
    def open(
        cls,
        path: str | Path,
        *,
        create: bool = True,
        busy_timeout_s: float = 5.0,
        clock: Clock | None = None,
        chain_format: int | None = None,
        readonly: bool = False,
    ) -> Store:
        """Open (and with `create`, make) a store; a bad or foreign file raises StoreFileError.

        `chain_format` chooses the chain of a store with no entries yet (default 2, a chain per run
        and the lab's; 1 is the single chain of stores written before it, kept for them).
        `readonly`: only read (a store on read-only media reads; a write raises StoreError saying so).
        """
        if is_url(path):
            return cls._open_url(str(path), create, busy_timeout_s, clock, chain_format)
        path = Path(path)
        conn = connect(path, create=create, busy_timeout_s=busy_timeout_s, readonly=readonly)
        if chain_format is not None:
            try:
                conn.execute("BEGIN IMMEDIATE")
                set_chain_format(conn, path, chain_format)
                conn.execute("COMMIT")
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                conn.close()
                raise
        store = cls(conn, path, clock or _utc_now)
        store.readonly = readonly
        if not readonly:  # a writer notices its files deleted, replaced or cut short at the next write
            store._guard = _guard.FileGuard(path)
        return store

    @classmethod
    def _open_url(
        cls, url: str, create: bool, timeout_s: float, clock: Clock | None, chain_format: int | None
    ) -> Store:
        if url.startswith("sqlite:"):
            raise StoreFileError(f"{url}: give a SQLite store as a file path")
        if chain_format not in (None, 2):
            raise StoreFileError(f"{safe_url(url)}: a PostgreSQL store has chain format 2 only")
        return cls(connect_pg(url, create=create, timeout_s=timeout_s), safe_url(url), clock or _utc_now)

    @property
    def path(self) -> Path:
        """The store's file (a SQLite store; a PostgreSQL store has none: StoreError)."""
        if not isinstance(self._path, Path):
            raise StoreError(f"{self._path}: a PostgreSQL store has no file")
        return self._path

    @property
    def location(self) -> str:
        """Where the records are: the file, or the database URL without its password."""
        return str(self._path)

    def close(self) -> None:
        """Close the file; further calls raise StoreError. Closing twice is harmless."""
        with self._lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # --- writing -------------------------------------------------------------------------

    def register_bat(self, bat_id: str, spec: dict[str, Any]) -> LogEntry:
        """Record a bat (rig-level 'BatRegistered' entry); an id is registered once only."""
        check_id("bat_id", bat_id)
        with self._write() as conn:
            if conn.execute("SELECT 1 FROM bats WHERE id = ?", (bat_id,)).fetchone():
                raise RecordRefused(f"bat {bat_id} is already registered")
            entry = self._append(conn, None, BAT_REGISTERED, {"bat_id": bat_id, "spec": spec})
            conn.execute("INSERT INTO bats (id, spec) VALUES (?, ?)", (bat_id, check_payload(spec)))
        return entry

    def register_lot(self, lot: Any) -> LogEntry:
        """Record a ball lot (a rig.core.ball.BallLot or its dict; lab-level 'BallLotRegistered').

        An id is registered once only (RecordRefused); a lot that does not validate is refused
        naming its first bad field.
        """
        spec = _lots.checked_lot(lot)
        with self._write() as conn:
            if self.engine != "sqlite":
                conn.lock_chain(LAB_CHAIN)  # two rigs registering one lot: the second waits, then sees it
            if spec["id"] in _lots.registered(conn):
                raise RecordRefused(f"ball lot {spec['id']} is already registered")
            return self._append(conn, None, BALL_LOT_REGISTERED, {"lot_id": spec["id"], "lot": spec})

    def ball_lots(self) -> dict[str, Any]:
        """Every registered ball lot (rig.core.ball.BallLot) by id, in registration order."""
        with self._read() as conn:
            return _lots.registered(conn)

    def ball_lot(self, lot_id: str) -> tuple[Any, list[Any]]:
        """(BallLot, its LotResults oldest first); an unknown id raises UnknownRecord naming known ones.

        A result is the `lot_result` of a finished ball-test run of the lot (RunFinished), with
        that run's id: it is covered by the run's chain, and derived from the run's shots.
        """
        lots = self.ball_lots()
        if lot_id not in lots:
            raise _lots.unknown(lot_id, lots)
        return lots[lot_id], _lots.results(self, lot_id)

    def record_ball_law(self, lot_id: str, text: str) -> LogEntry:
        """Record `text` (a ball file, as `rig model fit-ball` wrote it) as lot `lot_id`'s ball law
        (lab-level 'BallLawRecorded'); the latest recorded is the lot's. An unknown lot raises
        UnknownRecord. The caller checks that the text is a ball law of this lot (rig.ball_rules)."""
        sha = _lots.law_sha256(text)
        with self._write() as conn:
            if self.engine != "sqlite":
                conn.lock_chain(LAB_CHAIN)
            lots = _lots.registered(conn)
            if lot_id not in lots:
                raise _lots.unknown(lot_id, lots)
            payload = {"lot_id": lot_id, "sha256": sha, "text": text}
            return self._append(conn, None, BALL_LAW_RECORDED, payload)

    def ball_laws(self, lot_id: str) -> list[_lots.RecordedLaw]:
        """The ball laws recorded for `lot_id`, oldest first ([] if none; the last is the lot's)."""
        with self._read() as conn:
            return _lots.laws(conn, lot_id)

    def ccor_points(self, lot_id: str) -> list[tuple[float, float, float, str]]:
        """The lot's CCOR points for fitting the ball law: (speed_m_s, ccor, u_ccor, ball_id).

        One point per valid hit of every finished `ccor` test of the lot, oldest run first:
        speed_m_s is the measured inbound speed at the cylinder's face (drag corrected), ccor the
        rebound over the inbound speed there, u_ccor that hit's standard uncertainty (its GUM
        budget: timing, gate positions, drag; the lot's ball-to-ball spread is not in it), ball_id
        the ball (LOT-01, ...). An unknown lot raises UnknownRecord; a lot with no ccor test gives [].
        """
        return _lots.points(self.ball_lot(lot_id)[1])

    def create_run(self, procedure: str, bat_id: str, meta: dict[str, Any]) -> str:
        """Start a run of `procedure` on a registered bat ('RunCreated' entry); returns its id."""
        check_id("procedure", procedure)
        run_id = uuid.uuid4().hex
        with self._write() as conn:
            if not conn.execute("SELECT 1 FROM bats WHERE id = ?", (bat_id,)).fetchone():
                known = [b for (b,) in conn.execute("SELECT id FROM bats ORDER BY id")]
                raise UnknownRecord(f"no bat {bat_id!r}; {known_ids('bats', known)}")
            payload = {"procedure": procedure, "bat_id": bat_id, "meta": meta}
            entry = self._append(conn, run_id, RUN_CREATED, payload, new_run=True)
            self._opened(conn, run_id, entry)
        return run_id

    def append(self, run_id: str | None, kind: str, payload: dict[str, Any]) -> LogEntry:
        """Append one entry (run_id None: rig-level); committed and synced when it returns."""
        return self.append_many([(run_id, kind, payload)])[0]

    def append_many(self, items: Iterable[EntrySpec]) -> list[LogEntry]:
        """Append several (run_id, kind, payload) entries in one transaction: all or none."""
        items = list(items)
        for _, kind, _ in items:
            if check_kind(kind) in RESERVED_KINDS:
                raise RecordRefused(f"kind {kind} is written by the store itself; use its own method")
        with self._write() as conn:
            return [self._append(conn, run_id, kind, payload) for run_id, kind, payload in items]

    def set_run_status(self, run_id: str, status: str, verdict: str | None = None) -> LogEntry:
        """Finish or abort a running run ('RunStatusChanged' entry), with an optional verdict."""
        if status not in _CLOSED_STATUSES:
            raise RecordRefused(f"status {status!r}: a run can only become one of {_CLOSED_STATUSES}")
        if verdict is not None and not isinstance(verdict, str):
            raise RecordRefused(f"verdict {verdict!r}: must be a str or None")
        with self._write() as conn:
            current = self._run(conn, run_id).status
            if current != "running":
                raise RecordRefused(f"run {run_id} is already {current}")
            entry = self._append(conn, run_id, RUN_STATUS_CHANGED, {"status": status, "verdict": verdict})
            self._sealed(conn, run_id, entry)
        return entry

    def _opened(self, conn: Any, run_id: str, created: LogEntry) -> None:
        """The runs row of a new run from its RunCreated, and (format 2) its RunOpened anchor."""
        p = created.payload
        conn.execute(
            f"INSERT INTO runs ({_RUN_COLUMNS}) VALUES (?, ?, ?, ?, 'running', NULL, ?)",
            (run_id, p["procedure"], p["bat_id"], created.t_utc, created.seq),
        )
        if self.chain_format == 2:  # the lab chain anchors the run's first entry
            self._append(conn, None, RUN_OPENED, {"run_id": run_id, "hash": created.hash})

    def _sealed(self, conn: Any, run_id: str, closing: LogEntry) -> None:
        """The runs row closed by a RunStatusChanged, and (format 2) its RunSealed anchor."""
        status, verdict = closing.payload.get("status"), closing.payload.get("verdict")
        conn.execute("UPDATE runs SET status = ?, verdict = ? WHERE run_id = ?", (status, verdict, run_id))
        if self.chain_format == 2:  # the lab chain anchors the sealed run's last entry
            anchor = {"run_id": run_id, "chain_seq": closing.chain_seq, "hash": closing.hash}
            self._append(conn, None, RUN_SEALED, {**anchor, "status": status})

    def import_chain(self, run_id: str, entries: list[LogEntry], source: str) -> int:
        """Add a run's entries copied verbatim from another store (chain format 2; rig sync).

        Entries the store already holds must be the same (same hashes, same order); only the
        missing tail is added, so importing twice adds nothing. Any difference, or a run another
        runner holds here, is refused (RecordRefused) before anything is written. Returns how
        many entries were added.
        """
        if self.chain_format != 2:
            raise RecordRefused(f"{self._path}: chain format 1 cannot take runs from other stores")
        with self._write() as conn:
            if self.engine != "sqlite":
                conn.lock_chain(run_id)
            held = [
                (n, h)
                for n, h in conn.execute(
                    "SELECT chain_seq, hash FROM log WHERE chain = ? ORDER BY chain_seq", (run_id,)
                )
            ]
            conflict = _sync.conflict(run_id, held, entries)
            if conflict:
                raise RecordRefused(conflict)
            new = entries[len(held) :]
            if not new:
                return 0
            if held:
                self._check_open(conn, run_id, new[0].kind)
            for entry in new:
                here = replace(entry, seq=self._insert_verbatim(conn, run_id, entry))  # its seq in this store
                if here.kind == RUN_CREATED:
                    self._opened(conn, run_id, here)
                    continue
                conn.execute("UPDATE runs SET last_seq = ? WHERE run_id = ?", (here.seq, run_id))
                if here.kind == RUN_STATUS_CHANGED:
                    self._sealed(conn, run_id, here)
            last = new[-1]
            synced = {"run_id": run_id, "source": source, "entries": len(new), "chain_seq": last.chain_seq}
            self._append(conn, None, RUN_SYNCED, {**synced, "hash": last.hash})
        return len(new)

    def _insert_verbatim(self, conn: Any, run_id: str, e: LogEntry) -> int:
        text = check_payload(e.payload)
        row = (run_id, e.kind, text, e.t_utc, e.prev_hash, e.hash, run_id, e.chain_seq)
        if entry_hash(e.prev_hash, e.chain_seq or 0, run_id, e.kind, e.t_utc, text) != e.hash:
            raise RecordRefused(f"run {run_id} entry {e.chain_seq}: its hash does not match its content")
        columns = "run_id, kind, payload, t_utc, prev_hash, hash, chain, chain_seq"
        if self.engine == "sqlite":
            last = conn.execute("SELECT seq FROM log ORDER BY seq DESC LIMIT 1").fetchone()
            seq = last[0] + 1 if last else 1
            conn.execute(f"INSERT INTO log (seq, {columns}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)", (seq, *row))
            return int(seq)
        return int(
            conn.execute(
                f"INSERT INTO log ({columns}) VALUES (?, ?, ?, ?, ?, ?, ?, ?) RETURNING seq", row
            ).fetchone()[0]
        )

    # --- one runner per run ----------------------------------------------------------------

    @contextmanager
    def run_lock(self, run_id: str, *, lease_s: float = DEFAULT_LEASE_S) -> Iterator[_lock.RunLock]:
        """Hold the run's lock while the block runs (renewed by a heartbeat); see `acquire_run`."""
        held = self.acquire_run(run_id, lease_s=lease_s)
        beat = _lock.Heartbeat(lambda: self._renew(held), f"run-lock-heartbeat-{run_id[:8]}", lease_s / 4)
        beat.start()
        try:
            yield held
        finally:
            beat.stop()
            self.release_run(held)

    def acquire_run(self, run_id: str, *, lease_s: float = DEFAULT_LEASE_S) -> _lock.RunLock:
        """Become the run's only runner, or raise RunLocked naming the one who is.

        A sealed (finished or aborted) run is refused. A stale lock (its process gone from this
        host, or its lease run out) is broken and a 'RunLockBroken' entry records whose it was.
        While this Store holds the lock, appends to the run from any other runner are refused.
        """
        if not isinstance(lease_s, int | float) or not math.isfinite(lease_s) or not 0 < lease_s <= 86400:
            raise RecordRefused(f"lease_s = {lease_s!r}: must be a number of seconds in (0, 86400]")
        with self._write() as conn:
            run = self._run(conn, run_id)
            if run.status != "running":
                raise RecordRefused(f"run {run_id} is {run.status}: it is sealed, there is nothing to run")
            now = self._clock().astimezone(UTC)
            stamp = now.isoformat(timespec="microseconds")
            owner, host = uuid.uuid4().hex, _lock.this_host()
            mine = _lock.RunLock(run_id, owner, host, os.getpid(), stamp, stamp, float(lease_s))
            held = _lock.read(conn, run_id)
            why = None if held is None else _lock.stale_reason(held, now)
            if held is not None and why is None:
                raise _lock.RunLocked(_lock.refusal(run_id, held))
            if held is not None:
                _lock.remove(conn, run_id, held.owner)
            _lock.insert(conn, mine)
            self._held[run_id] = mine.owner
            try:
                if held is not None:
                    payload = {"holder": held.as_payload(), "reason": why, "taken_by": mine.as_payload()}
                    self._append(conn, run_id, RUN_LOCK_BROKEN, payload)
            except BaseException:
                self._held.pop(run_id, None)
                raise
        return mine

    def release_run(self, held: _lock.RunLock) -> None:
        """Give the run's lock back (harmless if it was broken meanwhile or the store is closed)."""
        with self._lock:
            if self._held.get(held.run_id) == held.owner:
                del self._held[held.run_id]
        try:
            with self._write() as conn:
                _lock.remove(conn, held.run_id, held.owner)
        except StoreError:
            pass  # closed store: the row goes stale with this process (same host) or its lease

    def run_lock_holder(self, run_id: str) -> _lock.RunLock | None:
        """The run's current lock row, if any (stale or not)."""
        with self._read() as conn:
            return _lock.read(conn, run_id)

    def _renew(self, held: _lock.RunLock) -> bool:
        stamp = self._clock().astimezone(UTC).isoformat(timespec="microseconds")
        with self._write() as conn:
            return _lock.renew(conn, held.run_id, held.owner, stamp)

    def rebuild_indexes(self) -> None:
        """Recompute `bats` and `runs` from the log (refuses if the log contradicts itself)."""
        with self._write() as conn:
            deriver = _derive.derive(conn)
            if deriver.problems:
                raise StoreError(f"{self._path}: cannot rebuild: " + "; ".join(deriver.problems[:5]))
            _derive.write_tables(conn, deriver)

    # --- reading -------------------------------------------------------------------------

    def entries(
        self, run_id: str | None = None, kinds: Iterable[str] | None = None, after_seq: int = 0
    ) -> list[LogEntry]:
        """Entries in seq order: of one run (or all), of some kinds (or all), after a seq."""
        where = ["seq > ?"]
        params: list[object] = [after_seq]
        if run_id is not None:
            where.append("run_id = ?")
            params.append(run_id)
        if kinds is not None:
            kinds = list(kinds)
            where.append(f"kind IN ({', '.join('?' * len(kinds))})")
            params += kinds
        sql = f"SELECT {ENTRY_COLUMNS} FROM log WHERE {' AND '.join(where)} ORDER BY seq"
        with self._read() as conn:
            return [entry_from_row(row) for row in conn.execute(sql, params)]

    def entry(self, seq: int) -> LogEntry | None:
        """The entry at `seq`, or None if there is none."""
        with self._read() as conn:
            row = conn.execute(f"SELECT {ENTRY_COLUMNS} FROM log WHERE seq = ?", (seq,)).fetchone()
        return entry_from_row(row) if row else None

    def runs(self) -> list[RunSummary]:
        """Every run, oldest first."""
        with self._read() as conn:
            order = "rowid" if self.engine == "sqlite" else "last_seq"  # PostgreSQL has no rowid
            rows = conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs ORDER BY started_utc, {order}")
            return [RunSummary(*row) for row in rows]

    def open_runs(self) -> list[RunSummary]:
        """Runs still 'running' (e.g. after a crash), oldest first: candidates for resuming."""
        return [r for r in self.runs() if r.status == "running"]

    def run(self, run_id: str) -> RunSummary:
        """One run; an unknown id raises UnknownRecord listing known ones."""
        with self._read() as conn:
            return self._run(conn, run_id)

    def bats(self) -> dict[str, dict[str, Any]]:
        """Every registered bat's spec, by id."""
        with self._read() as conn:
            return {
                bat_id: decode_payload(spec) for bat_id, spec in conn.execute("SELECT id, spec FROM bats")
            }

    def view_rows(self, view: str, run_id: str | None = None) -> list[dict[str, Any]]:
        """Rows of an analysts' view (`shots`, `runs_summary`; docs/records.md), of one run or all."""
        with self._read() as conn:
            return _views.read_view(conn, view, run_id)

    def head(self) -> Anchor:
        """Seq and hash of the latest entry ((0, 64 zeros) when empty): print it as an anchor."""
        with self._read() as conn:
            row = conn.execute("SELECT seq, hash FROM log ORDER BY seq DESC LIMIT 1").fetchone()
        return Anchor(*row) if row else Anchor(0, GENESIS_HASH)

    def head_hash(self) -> str:
        """Hash of the latest entry; only a copy kept outside the file reveals a cut-off tail."""
        return self.head().hash

    def verify(self, anchors: Iterable[Anchor] = ()) -> VerifyReport:
        """Walk the chain from genesis, cross-check the tables and any outside anchors."""
        anchors = list(anchors)
        with self._snapshot() as conn:
            report = _verify.verify(conn, anchors, self.chain_format, self.engine)
            return _signed.with_signatures(conn, report, self.engine)

    def verify_run(self, run_id: str) -> VerifyReport:
        """One run: its own chain and its anchors in the lab chain (chain format 2; format 1 has
        one chain through every run, so the whole store is verified)."""
        self.run(run_id)  # an unknown run: UnknownRecord naming the known ones
        if self.chain_format == 1:
            return self.verify()
        with self._snapshot() as conn:
            return _verify.verify_run(conn, run_id, self.engine)

    def check_integrity(self, run_id: str | None = None) -> None:
        """The cheap check before recording a run (rig.store._integrity): the file is sound (SQLite's
        quick_check), the chain head the next entry links to holds, and with `run_id` its chain
        holds; else StoreDamaged (a StoreError) naming the first problem."""
        with self._read() as conn:  # outside a transaction: a damaged page may end it
            found = _integrity.file_problem(conn) if self.engine == "sqlite" else None
        if not found:
            with self._snapshot() as conn:
                found = _integrity.chain_problem(conn, self.chain_format, run_id)
        if found:
            raise _integrity.StoreDamaged(f"{self._path}: {found} (rig verify says more)")

    def confirm_sealed(self, run_id: str, seal: LogEntry) -> None:
        """After sealing a run: read it back as another reader would (a SQLite store through a new
        connection to its path: a file deleted or replaced meanwhile is found) and check that it is
        sealed at `seal` and holds (check_integrity; in chain format 2 also its anchors in the lab
        chain). A verdict is reported only after this; else StoreError naming what is wrong."""
        if self._guard is not None:
            self._guard.check()
        if self.engine != "sqlite":
            self._confirm(run_id, seal)
            return
        try:
            fresh = Store.open(self.path, create=False, readonly=True)
        except StoreError as exc:
            raise StoreError(f"{exc}; run {run_id} was sealed but cannot be read back") from None
        with fresh:
            fresh._confirm(run_id, seal)

    def _confirm(self, run_id: str, seal: LogEntry) -> None:
        run = self.run(run_id)
        last = self.entry(run.last_seq)
        if run.status not in _CLOSED_STATUSES or last is None or last.hash != seal.hash:
            raise StoreError(
                f"{self._path}: run {run_id} does not read back as sealed at entry {seal.seq} "
                f"(status {run.status}, last entry {run.last_seq})"
            )
        self.check_integrity(run_id)  # StoreDamaged names what is wrong
        if self.chain_format == 2:
            report = self.verify_run(run_id)
            if not report.ok:
                raise StoreError(
                    f"{self._path}: run {run_id} does not verify once sealed: {report.problems[0]}"
                )

    def pragmas(self) -> dict[str, Any]:
        """The connection's journal_mode, synchronous, foreign_keys and busy_timeout (diagnostics)."""
        names = ("journal_mode", "synchronous", "foreign_keys", "busy_timeout")
        with self._read() as conn:
            return {name: conn.execute(f"PRAGMA {name}").fetchone()[0] for name in names}

    # --- internals -----------------------------------------------------------------------

    @contextmanager
    def _read(self) -> Iterator[Any]:
        with self._lock:
            if self._conn is None:
                raise StoreError(f"{self._path}: the store is closed")
            try:
                yield self._conn
            except sqlite3.Error as exc:
                raise StoreError(f"{self._path}: {exc}") from exc
            except Exception as exc:
                if self.engine == "sqlite" or not is_db_error(exc):
                    raise
                raise StoreError(f"{self._path}: {db_error_text(exc)}") from exc

    @contextmanager
    def _snapshot(self) -> Iterator[Any]:
        """One read snapshot: a concurrent append must not look like a mismatch to a verifier."""
        with self._read() as conn:
            conn.execute("BEGIN" if self.engine == "sqlite" else "BEGIN ISOLATION LEVEL REPEATABLE READ")
            try:
                yield conn
            finally:
                if conn.in_transaction:
                    conn.execute("COMMIT")

    @contextmanager
    def _write(self) -> Iterator[Any]:
        # IMMEDIATE takes the write lock before reading the head, so that two writers (even in
        # two processes) can never both append after the same entry.
        if self.readonly:
            raise StoreError(f"{self._path}: opened read-only; writing to it needs a store opened to write")
        with self._read() as conn:
            if self._guard is not None:
                self._guard.check()
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
                conn.execute("COMMIT")
            except BaseException:
                if conn.in_transaction:  # also when COMMIT itself failed
                    conn.execute("ROLLBACK")
                raise
            if self._guard is not None:  # committed, but into the files this store opened?
                self._guard.check()

    def _append(
        self,
        conn: Any,
        run_id: str | None,
        kind: str,
        payload: dict[str, Any],
        *,
        new_run: bool = False,
    ) -> LogEntry:
        text = check_payload(payload)
        if run_id is not None and not isinstance(run_id, str):
            raise RecordRefused(f"run_id {run_id!r}: must be a str or None")
        if run_id is not None and not new_run:
            self._check_open(conn, run_id, kind)
        t_utc = self._clock().astimezone(UTC).isoformat(timespec="microseconds")
        if self.engine != "sqlite":
            return self._append_pg(conn, run_id, kind, text, t_utc, new_run)
        last = conn.execute("SELECT seq FROM log ORDER BY seq DESC LIMIT 1").fetchone()
        seq = last[0] + 1 if last else 1
        chain: str | None = None
        number: int | None = None
        if self.chain_format == 1:  # one chain through every entry, numbered by seq
            head = conn.execute("SELECT hash FROM log WHERE seq = ?", (seq - 1,)).fetchone()
            prev_hash, hashed_seq = (head[0] if head else GENESIS_HASH), seq
        else:  # the run's own chain, or the lab's, numbered within it
            chain = run_id if run_id is not None else LAB_CHAIN
            head = conn.execute(
                "SELECT chain_seq, hash FROM log WHERE chain = ? ORDER BY chain_seq DESC LIMIT 1", (chain,)
            ).fetchone()
            number, prev_hash = (head[0] + 1, head[1]) if head else (1, GENESIS_HASH)
            hashed_seq = number
        digest = entry_hash(prev_hash, hashed_seq, run_id, kind, t_utc, text)
        conn.execute(
            "INSERT INTO log (seq, run_id, kind, payload, t_utc, prev_hash, hash, chain, chain_seq) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (seq, run_id, kind, text, t_utc, prev_hash, digest, chain, number),
        )
        if run_id is not None and not new_run:
            conn.execute("UPDATE runs SET last_seq = ? WHERE run_id = ?", (seq, run_id))
        return LogEntry(seq, run_id, kind, decode_payload(text), t_utc, prev_hash, digest, number)

    def _append_pg(
        self, conn: Any, run_id: str | None, kind: str, text: str, t_utc: str, new_run: bool
    ) -> LogEntry:
        """Append to the run's chain (or the lab's) under that chain's lock only."""
        chain = run_id if run_id is not None else LAB_CHAIN
        conn.lock_chain(chain)
        head = conn.execute(
            "SELECT chain_seq, hash FROM log WHERE chain = ? ORDER BY chain_seq DESC LIMIT 1", (chain,)
        ).fetchone()
        number, prev_hash = (head[0] + 1, head[1]) if head else (1, GENESIS_HASH)
        digest = entry_hash(prev_hash, number, run_id, kind, t_utc, text)
        insert = (
            "INSERT INTO log (run_id, kind, payload, t_utc, prev_hash, hash, chain, chain_seq) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?) RETURNING seq"
        )
        row = (run_id, kind, text, t_utc, prev_hash, digest, chain, number)
        if run_id is not None and not new_run:  # the entry and the run's last_seq in one round trip
            update = "UPDATE runs SET last_seq = (SELECT seq FROM e) WHERE run_id = ? RETURNING last_seq"
            sql = f"WITH e AS ({insert}) {update}"
            seq = conn.execute(sql, (*row, run_id)).fetchone()[0]
        else:
            seq = conn.execute(insert, row).fetchone()[0]
        return LogEntry(seq, run_id, kind, decode_payload(text), t_utc, prev_hash, digest, number)

    def _check_open(self, conn: Any, run_id: str, kind: str) -> None:
        """Refuse an entry for an unknown or sealed run, or one another runner holds (one query)."""
        columns = ", ".join(f"l.{c.strip()}" for c in _lock.COLUMNS.split(","))
        row = conn.execute(
            f"SELECT r.status, r.last_seq, {columns} FROM runs r "
            "LEFT JOIN run_locks l ON l.run_id = r.run_id WHERE r.run_id = ?",
            (run_id,),
        ).fetchone()
        if row is None:
            self._run(conn, run_id)  # refuses an unknown run with the known ids
        status, last_seq, lock_row = row[0], row[1], row[2:]
        if status != "running":
            raise RecordRefused(
                f"run {run_id} is {status} and sealed at seq {last_seq}: no {kind} may follow it"
            )
        held = _lock.RunLock(*lock_row) if lock_row[0] is not None else None
        mine = self._held.get(run_id)
        if held is not None and held.owner != mine:
            raise _lock.RunLocked(_lock.refusal(run_id, held))
        if held is None and mine is not None:
            raise _lock.RunLocked(f"run {run_id}: this runner's lock was broken (lease ran out); stopping")

    def _run(self, conn: Any, run_id: str) -> RunSummary:
        row = conn.execute(f"SELECT {_RUN_COLUMNS} FROM runs WHERE run_id = ?", (run_id,)).fetchone()
        if row is None:
            recent = [r for (r,) in conn.execute("SELECT run_id FROM runs ORDER BY started_utc DESC")]
            close = [r for r in recent if isinstance(run_id, str) and run_id and r.startswith(run_id)]
            hint = f"did you mean {', '.join(close[:3])}?" if close else known_ids("runs", recent)
            raise UnknownRecord(f"no run {run_id!r}; {hint}")
        return RunSummary(*row)
