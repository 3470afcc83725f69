"""Walking the hash chain from genesis, cross-checking the tables and checking outside anchors."""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any, cast

from rig.core import events as ev
from rig.store._chains import Chains, check_anchors, check_chain
from rig.store._codec import GENESIS_HASH, entry_hash
from rig.store._derive import Deriver, compare_tables
from rig.store._order import hashed_seq
from rig.store._records import LAB_CHAIN, Anchor, VerifyReport
from rig.store._schema import APPEND_ONLY_TRIGGERS

_TEXT_COLUMNS = ("run_id", "kind", "payload", "t_utc", "prev_hash", "hash")
_MAX_LISTED = 50  # a wholesale rewrite would otherwise list every row

# Raw bytes and storage class of every column: a tampered row may hold invalid UTF-8 or a BLOB,
# which must be reported as a broken entry rather than crash the reader.
_SELECT = (
    "SELECT seq, "
    + ", ".join(f"CAST({c} AS BLOB), typeof({c})" for c in _TEXT_COLUMNS)
    + ", chain, chain_seq FROM log ORDER BY seq"
)
# PostgreSQL keeps text valid UTF-8 in a UTF-8 database: its bytes and whether it is NULL suffice
_SELECT_PG = (
    "SELECT seq, "
    + ", ".join(
        f"convert_to({c}, 'UTF8'), CASE WHEN {c} IS NULL THEN 'null' ELSE 'text' END" for c in _TEXT_COLUMNS
    )
    + ", chain, chain_seq FROM log ORDER BY seq"
)


class _Chain:
    """Checks rows one by one: seq continuity, link to the previous hash, the row's own hash."""

    def __init__(self) -> None:
        self.expected_seq = 1
        self.prev_hash = GENESIS_HASH
        self.checked = 0
        self.head = Anchor(0, GENESIS_HASH)
        self.problems: list[tuple[int, str]] = []
        self.unlinked: dict[int, tuple[str | None, ...]] = {}  # seq -> the fields of a row that does not link

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
                if len(self.unlinked) < _MAX_LISTED:
                    self.unlinked[seq] = fields
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

    def moved(self, conn: Any) -> None:
        """Name the rows that do not link because they were moved: each one's own hash says at which
        seq it was written (an entry out of place), or its predecessor is the one that moved."""
        found: dict[int, str] = {}
        for seq, fields in self.unlinked.items():
            prev_hash = fields[4]
            row = conn.execute("SELECT seq FROM log WHERE hash = ?", (prev_hash,)).fetchone()
            before = 0 if prev_hash == GENESIS_HASH else (row[0] if row else None)
            candidates = [*self.unlinked, *([] if before is None else [before + 1])]
            written = hashed_seq(seq, candidates, fields)
            if written is not None and written != seq:
                found[seq] = (
                    f"out of place: its hash places it at seq {written} "
                    "(moved: entries reordered, inserted or removed)"
                )
            elif written == seq and before is not None and before != seq - 1:
                found[seq] = f"prev_hash mismatch: the entry before it was moved (it is now at seq {before})"
        self.problems = [(seq, found.get(seq, why)) for seq, why in self.problems]


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


def verify(
    conn: Any, anchors: Iterable[Anchor] = (), chain_format: int = 1, engine: str = "sqlite"
) -> VerifyReport:
    """Check the log, the tables and the anchors (caller holds a read transaction)."""
    chain, deriver, audit, chains = _Chain(), Deriver(), _RunAudit(), Chains()
    last = Anchor(0, GENESIS_HASH)
    for row in conn.execute(_SELECT if engine == "sqlite" else _SELECT_PG):
        seq, raw, chain_name, chain_seq = row[0], row[1:-2], row[-2], row[-1]
        if chain_format == 1:
            fields = chain.feed(seq, raw)
        else:
            chain.checked += 1
            fields, why = _decode(raw)
            if why is not None:
                chains.problems.append((seq, why))
                fields = None
            else:
                chains.feed(seq, chain_name, chain_seq, fields)
                last = Anchor(seq, str(fields[5]))
        if fields is not None:
            run_id, kind, payload, t_utc = fields[:4]
            deriver.feed(seq, run_id, kind or "", payload, t_utc or "")
            audit.feed(seq, run_id, kind or "", payload)
    if chain.unlinked:
        chain.moved(conn)
    broken = list(chain.problems)
    extra: list[str] = []
    if chain_format == 2:
        broken += chains.problems
        for name, rows in chains.rows.items():
            broken += check_chain(name, rows)[0]
        broken.sort()
        extra = check_anchors(chains.rows)
        chain.head = last
    problems = [f"seq {seq}: {reason}" for seq, reason in broken[:_MAX_LISTED]]
    if len(broken) > _MAX_LISTED:
        problems.append(f"... and {len(broken) - _MAX_LISTED} more broken entries")
    problems += extra[:_MAX_LISTED]
    problems += deriver.problems[:_MAX_LISTED]
    problems += audit.problems[:_MAX_LISTED]
    problems += compare_tables(conn, deriver)[:_MAX_LISTED]
    problems += _check_anchors(conn, anchors, engine)
    problems += _check_triggers(conn, engine)
    first = broken[0] if broken else (None, None)
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
            # CAST AS BLOB (sqlite) or convert_to (PostgreSQL) of a text column: bytes
            values.append(bytes(cast("bytes | memoryview", data)).decode("utf-8"))
        except UnicodeDecodeError:
            return (), f"{column} is not valid UTF-8 text (changed after it was written)"
    return tuple(values), None


def _check_anchors(conn: Any, anchors: Iterable[Anchor], engine: str) -> list[str]:
    problems = []
    raw_hash = "CAST(hash AS BLOB)" if engine == "sqlite" else "convert_to(hash, 'UTF8')"
    for anchor in anchors:
        row = conn.execute(f"SELECT {raw_hash} FROM log WHERE seq = ?", (anchor.seq,)).fetchone()
        if row is None:
            problems.append(f"anchor seq {anchor.seq}: no such entry (the log was truncated)")
        elif bytes(row[0]) != anchor.hash.encode():
            problems.append(
                f"anchor seq {anchor.seq}: hash is {bytes(row[0]).decode(errors='replace')}, the anchor "
                f"says {anchor.hash} (the log was rewritten)"
            )
    return problems


def _check_triggers(conn: Any, engine: str) -> list[str]:
    query = (
        "SELECT name FROM sqlite_master WHERE type = 'trigger'"
        if engine == "sqlite"
        else "SELECT tgname FROM pg_trigger WHERE tgrelid = 'log'::regclass AND tgenabled <> 'D'"
    )
    present = {name for (name,) in conn.execute(query)}
    missing = [name for name in APPEND_ONLY_TRIGGERS if name not in present]
    return [f"append-only triggers removed: {', '.join(missing)}"] if missing else []


def verify_run(conn: Any, run_id: str, engine: str = "sqlite") -> VerifyReport:
    """Chain format 2: one run's chain and the lab chain's anchors of it (caller holds a snapshot)."""
    select = (_SELECT if engine == "sqlite" else _SELECT_PG).replace(
        "FROM log ORDER BY seq", "FROM log WHERE chain IN (?, ?) ORDER BY seq"
    )
    chains = Chains()
    checked = 0
    for row in conn.execute(select, (run_id, LAB_CHAIN)):
        seq, raw, chain_name, chain_seq = row[0], row[1:-2], row[-2], row[-1]
        checked += 1
        fields, why = _decode(raw)
        if why is not None:
            chains.problems.append((seq, why))
        else:
            chains.feed(seq, chain_name, chain_seq, fields)
    broken = list(chains.problems)
    head = Anchor(0, GENESIS_HASH)
    for name, rows in chains.rows.items():
        found, last = check_chain(name, rows)
        broken += found
        if name == run_id and last is not None:
            head = last
    broken.sort()
    problems = [f"seq {seq}: {reason}" for seq, reason in broken[:_MAX_LISTED]]
    problems += check_anchors(chains.rows, only=run_id)
    if run_id not in chains.rows:
        problems.append(f"run {run_id}: no entries")
    first = broken[0] if broken else (None, None)
    return VerifyReport(
        ok=not problems,
        entries_checked=checked,
        head=head,
        first_broken_seq=first[0],
        reason=first[1],
        problems=tuple(problems),
    )
