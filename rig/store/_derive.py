"""The convenience tables (`bats`, `runs`) as a pure function of the log, and their cross-check."""

from __future__ import annotations

import sqlite3
from typing import Any

from rig.core.errors import StoreError
from rig.store._codec import canonical_json, decode_payload
from rig.store._records import (
    BALL_LAW_RECORDED,
    BALL_LOT_REGISTERED,
    BAT_REGISTERED,
    CLOSED_STATUSES,
    RUN_CREATED,
    RUN_STATUS_CHANGED,
    RUN_STATUSES,
)

RUN_COLUMNS = ("run_id", "procedure", "bat_id", "started_utc", "status", "verdict", "last_seq")
RunRow = tuple[str, str, str, str, str, str | None, int]


class Deriver:
    """Feed log entries in seq order; `bats` and `runs` then hold what the tables must hold."""

    def __init__(self) -> None:
        self.bats: dict[str, str] = {}  # id -> spec as canonical JSON
        self.runs: dict[str, list[Any]] = {}  # run_id -> a RUN_COLUMNS row
        self.sealed: dict[str, int] = {}  # run_id -> seq of the entry that closed it
        self.lots: set[str] = set()  # ball lots registered (they have no table: the log is theirs)
        self.problems: list[str] = []

    def feed(self, seq: int, run_id: str | None, kind: str, payload: str | None, t_utc: str) -> None:
        """Apply one entry; `payload` is needed only for the kinds the store writes itself."""
        try:
            self._apply(seq, run_id, kind, payload, t_utc)
        except (StoreError, KeyError, TypeError, AttributeError) as exc:
            self.problems.append(f"seq {seq}: {kind} entry unreadable ({exc!r})")

    def _apply(self, seq: int, run_id: str | None, kind: str, payload: str | None, t_utc: str) -> None:
        if kind == BAT_REGISTERED:
            self._bat(seq, _decoded(payload))
        elif kind == BALL_LOT_REGISTERED:
            lot_id = _decoded(payload)["lot_id"]
            if lot_id in self.lots:
                self.problems.append(f"seq {seq}: ball lot {lot_id} registered twice")
            self.lots.add(lot_id)
        elif kind == BALL_LAW_RECORDED:
            lot_id = _decoded(payload)["lot_id"]
            if lot_id not in self.lots:
                self.problems.append(f"seq {seq}: a ball law for lot {lot_id}, which was never registered")
        elif kind == RUN_CREATED:
            self._created(seq, run_id, _decoded(payload), t_utc)
        if run_id is None:
            return
        row = self.runs.get(run_id)
        if row is None:
            self.problems.append(f"seq {seq}: entry of run {run_id}, which was never created")
            return
        if run_id in self.sealed:
            # Not applied: a forged verdict must not become the run's status.
            self.problems.append(
                f"seq {seq}: {kind} appended to run {run_id} after it was sealed at seq "
                f"{self.sealed[run_id]} (nothing may follow a finished or aborted run's last entry)"
            )
            return
        row[6] = seq
        if kind == RUN_STATUS_CHANGED:
            change = _decoded(payload)
            status, verdict = change["status"], change.get("verdict")
            if status not in RUN_STATUSES:
                self.problems.append(f"seq {seq}: run {run_id} set to unknown status {status!r}")
                return
            row[4], row[5] = status, verdict
            if status in CLOSED_STATUSES:
                self.sealed[run_id] = seq

    def _bat(self, seq: int, payload: dict[str, Any]) -> None:
        bat_id = payload["bat_id"]
        if bat_id in self.bats:
            self.problems.append(f"seq {seq}: bat {bat_id} registered twice")
            return
        self.bats[bat_id] = canonical_json(payload["spec"])

    def _created(self, seq: int, run_id: str | None, payload: dict[str, Any], t_utc: str) -> None:
        if run_id is None or run_id in self.runs:
            self.problems.append(f"seq {seq}: RunCreated for a missing or duplicate run id {run_id!r}")
            return
        if payload["bat_id"] not in self.bats:
            self.problems.append(f"seq {seq}: run {run_id} uses unregistered bat {payload['bat_id']}")
        self.runs[run_id] = [run_id, payload["procedure"], payload["bat_id"], t_utc, "running", None, seq]


def derive(conn: sqlite3.Connection) -> Deriver:
    """Replay the whole log (reserved kinds decoded only) into a Deriver."""
    deriver = Deriver()
    rows = conn.execute(
        "SELECT seq, run_id, kind, CASE WHEN kind IN (?, ?, ?, ?, ?) THEN payload END, t_utc "
        "FROM log ORDER BY seq",
        (BAT_REGISTERED, RUN_CREATED, RUN_STATUS_CHANGED, BALL_LOT_REGISTERED, BALL_LAW_RECORDED),
    )
    for seq, run_id, kind, payload, t_utc in rows:
        deriver.feed(seq, run_id, kind, payload, t_utc)
    return deriver


def write_tables(conn: sqlite3.Connection, deriver: Deriver) -> None:
    """Replace the tables' contents by the derived ones (caller holds a write transaction)."""
    conn.execute("DELETE FROM runs")  # runs first: it references bats
    conn.execute("DELETE FROM bats")
    conn.executemany("INSERT INTO bats (id, spec) VALUES (?, ?)", deriver.bats.items())
    conn.executemany(
        f"INSERT INTO runs ({', '.join(RUN_COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?, ?)",
        (tuple(row) for row in deriver.runs.values()),
    )


def compare_tables(conn: sqlite3.Connection, deriver: Deriver) -> list[str]:
    """Every difference between the stored tables and what the log implies."""
    problems: list[str] = []
    stored_bats = dict(conn.execute("SELECT id, spec FROM bats"))
    _diff(
        "bats",
        {k: (v,) for k, v in stored_bats.items()},
        {k: (v,) for k, v in deriver.bats.items()},
        ("spec",),
        problems,
    )
    stored_runs = {row[0]: tuple(row) for row in conn.execute(f"SELECT {', '.join(RUN_COLUMNS)} FROM runs")}
    derived_runs = {k: tuple(v) for k, v in deriver.runs.items()}
    _diff("runs", stored_runs, derived_runs, RUN_COLUMNS, problems)
    return problems


def _diff(
    table: str,
    stored: dict[str, tuple[Any, ...]],
    derived: dict[str, tuple[Any, ...]],
    columns: tuple[str, ...],
    problems: list[str],
) -> None:
    for key in sorted(stored.keys() - derived.keys()):
        problems.append(f"table {table}: row {key} is not in the log")
    for key in sorted(derived.keys() - stored.keys()):
        problems.append(f"table {table}: row {key} is missing (the log has it)")
    for key in sorted(stored.keys() & derived.keys()):
        for column, have, want in zip(columns, stored[key], derived[key], strict=True):
            if have != want:
                problems.append(f"table {table}, row {key}: {column} is {have!r}, the log says {want!r}")


def _decoded(payload: str | None) -> dict[str, Any]:
    if payload is None:
        raise StoreError("payload missing")
    return decode_payload(payload)
