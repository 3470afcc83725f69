"""Walking the hash chain from genesis, cross-checking the tables and checking outside anchors."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable

from rig.core import events as ev
from rig.store._codec import GENESIS_HASH, entry_hash
from rig.store._derive import Deriver, compare_tables
from rig.store._records import Anchor, VerifyReport
from rig.store._schema import APPEND_ONLY_TRIGGERS

_TEXT_COLUMNS = ("run_id", "kind", "payload", "t_utc", "prev_hash", "hash")
_MAX_LISTED = 50  # a wholesale rewrite would otherwise list every row

# Raw bytes and storage class of every column: a tampered row may hold invalid UTF-8 or a BLOB,
# which must be reported as a broken entry rather than crash the reader.
_SELECT = (
    "SELECT seq, "
    + ", ".join(f"CAST({c} AS BLOB), typeof({c})" for c in _TEXT_COLUMNS)
    + " FROM log ORDER BY seq"
)


class _Chain:
    """Checks rows one by one: seq continuity, link to the previous hash, the row's own hash."""

    def __init__(self) -> None:
        self.expected_seq = 1
        self.prev_hash = GENESIS_HASH
        self.checked = 0
        self.head = Anchor(0, GENESIS_HASH)
        self.problems: list[tuple[int, str]] = []

    def feed(self, seq: int, raw: tuple[object, ...]) -> tuple[str | None, ...] | None:
        """Check one row; return its decoded text columns, or None if they cannot be read."""
        self.checked += 1
        fields, why = _decode(raw)
        if seq != self.expected_seq:
            gap = (
                f"{self.expected_seq}" if seq == self.expected_seq + 1 else f"{self.expected_seq}..{seq - 1}"
            )
            self._broken(seq, f"seq gap: seq {gap} missing (deleted rows?)")
        elif why is not None:
            self._broken(seq, why)
        else:
            run_id, kind, payload, t_utc, prev_hash, hash_ = fields
            if prev_hash != self.prev_hash:
                self._broken(
                    seq,
                    "prev_hash mismatch: does not link to the entry before it "
                    "(an entry was inserted, removed, reordered or re-hashed)",
                )
            elif entry_hash(prev_hash, seq, run_id, kind, t_utc, payload) != hash_:  # type: ignore[arg-type]
                self._broken(seq, "hash mismatch: the entry was changed after it was written")
        self.expected_seq = seq + 1
        # Continue from the stored hash so that later, independent breaks are reported too.
        stored_hash = fields[5] if why is None else None
        self.prev_hash = stored_hash or ""
        self.head = Anchor(seq, self.prev_hash)
        return fields if why is None else None

    def _broken(self, seq: int, reason: str) -> None:
        self.problems.append((seq, reason))


# Entries a run may hold once only, keyed by a payload field (None: once per run at all).
_ONCE_PER_RUN: dict[str, str | None] = {
    ev.SHOT_REQUESTED: "index",
    ev.SHOT_FIRED: "index",
    ev.RUN_FINISHED: None,
}


class _RunAudit:
    """Per run: a shot number requested or fired twice, a second verdict (two runners at once)."""

    def __init__(self) -> None:
        self.first: dict[tuple[str, str, object], int] = {}  # (run, kind, key) -> first seq
        self.problems: list[str] = []

    def feed(self, seq: int, run_id: str | None, kind: str, payload: str | None) -> None:
        if run_id is None or kind not in _ONCE_PER_RUN:
            return
        field = _ONCE_PER_RUN[kind]
        key: object = None
        if field is not None:
            try:
                key = json.loads(payload or "").get(field)
            except (ValueError, AttributeError):
                return  # an unreadable payload is the chain's finding
            if not isinstance(key, int):
                return
        first = self.first.setdefault((run_id, kind, key), seq)
        if first != seq:
            what = {
                ev.SHOT_FIRED: f"shot {key} fired twice",
                ev.SHOT_REQUESTED: f"shot {key} requested twice",
            }.get(kind, f"a second {kind}")
            self.problems.append(
                f"seq {seq}: run {run_id}: {what} (the first at seq {first}; two runners at once?)"
            )


def verify(conn: sqlite3.Connection, anchors: Iterable[Anchor] = ()) -> VerifyReport:
    """Check the log, the tables and the anchors (caller holds a read transaction)."""
    chain, deriver, audit = _Chain(), Deriver(), _RunAudit()
    for row in conn.execute(_SELECT):
        seq, raw = row[0], row[1:]
        fields = chain.feed(seq, raw)
        if fields is not None:
            run_id, kind, payload, t_utc = fields[:4]
            deriver.feed(seq, run_id, kind or "", payload, t_utc or "")
            audit.feed(seq, run_id, kind or "", payload)
    problems = [f"seq {seq}: {reason}" for seq, reason in chain.problems[:_MAX_LISTED]]
    if len(chain.problems) > _MAX_LISTED:
        problems.append(f"... and {len(chain.problems) - _MAX_LISTED} more broken entries")
    problems += deriver.problems[:_MAX_LISTED]
    problems += audit.problems[:_MAX_LISTED]
    problems += compare_tables(conn, deriver)[:_MAX_LISTED]
    problems += _check_anchors(conn, anchors)
    problems += _check_triggers(conn)
    first = chain.problems[0] if chain.problems else (None, None)
    return VerifyReport(
        ok=not problems,
        entries_checked=chain.checked,
        head=chain.head,
        first_broken_seq=first[0],
        reason=first[1],
        problems=tuple(problems),
    )


def _decode(raw: tuple[object, ...]) -> tuple[tuple[str | None, ...], str | None]:
    """The six text columns as str (run_id may be NULL), or why a column is unreadable."""
    values: list[str | None] = []
    for i, column in enumerate(_TEXT_COLUMNS):
        data, storage = raw[2 * i], raw[2 * i + 1]
        if storage == "null" and column == "run_id":
            values.append(None)
            continue
        if storage != "text":
            return (), f"{column} is stored as {storage}, not text"
        try:
            values.append(bytes(data).decode("utf-8"))  # type: ignore[arg-type]
        except UnicodeDecodeError:
            return (), f"{column} is not valid UTF-8 text (changed after it was written)"
    return tuple(values), None


def _check_anchors(conn: sqlite3.Connection, anchors: Iterable[Anchor]) -> list[str]:
    problems = []
    for anchor in anchors:
        row = conn.execute("SELECT CAST(hash AS BLOB) FROM log WHERE seq = ?", (anchor.seq,)).fetchone()
        if row is None:
            problems.append(f"anchor seq {anchor.seq}: no such entry (the log was truncated)")
        elif bytes(row[0]) != anchor.hash.encode():
            problems.append(
                f"anchor seq {anchor.seq}: hash is {bytes(row[0]).decode(errors='replace')}, the anchor "
                f"says {anchor.hash} (the log was rewritten)"
            )
    return problems


def _check_triggers(conn: sqlite3.Connection) -> list[str]:
    present = {name for (name,) in conn.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'")}
    missing = [name for name in APPEND_ONLY_TRIGGERS if name not in present]
    return [f"append-only triggers removed: {', '.join(missing)}"] if missing else []
