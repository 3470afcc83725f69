"""The cheap check before a run records into a store: is the file sound, do the heads it appends to
and the run's own chain hold? `rig verify` is the full check; this one runs before the cannon is
armed, so that no certification is recorded into a store that verify would call damaged.

- the file: SQLite's `PRAGMA quick_check` (about 0.1 s per 100 MB; PostgreSQL keeps its own);
- the chain head the next entry links to: the last entry (format 1) or the lab chain's last;
- with a run: every entry of its chain (a run holds hundreds of entries, not the whole store).
"""

from __future__ import annotations

import sqlite3
from typing import Any

from rig.core.errors import StoreError
from rig.store._chains import check_chain
from rig.store._codec import GENESIS_HASH, entry_hash
from rig.store._records import LAB_CHAIN

_COLUMNS = "seq, chain_seq, run_id, kind, payload, hash, prev_hash, t_utc"


class StoreDamaged(StoreError):
    """The store's file or a chain it appends to does not hold (Store.check_integrity)."""


def file_problem(conn: Any) -> str | None:
    """What SQLite's quick_check finds wrong with the file, as text, or None."""
    try:
        rows = conn.execute("PRAGMA quick_check").fetchall()
    except sqlite3.DatabaseError as exc:
        return f"damaged: {exc} (SQLite's quick_check)"
    if rows == [("ok",)]:
        return None
    return "damaged: " + "; ".join(str(r[0]) for r in rows[:3]) + " (SQLite's quick_check)"


def chain_problem(conn: Any, chain_format: int, run_id: str | None) -> str | None:
    """The first break in the chain head the next entry links to, or in the run's chain, as text,
    or None (caller holds a read snapshot)."""
    if chain_format == 1:
        return _format1(conn, run_id)
    lab = conn.execute(
        f"SELECT {_COLUMNS} FROM log WHERE chain = ? ORDER BY chain_seq DESC LIMIT 2", (LAB_CHAIN,)
    ).fetchall()
    if lab and not _links(lab[0], lab[1][5] if len(lab) > 1 else GENESIS_HASH, lab[0][1]):
        return (
            f"the lab chain's last entry {lab[0][1]} (seq {lab[0][0]}) does not hold (changed or re-linked)"
        )
    if run_id is not None:
        rows = conn.execute(f"SELECT {_COLUMNS} FROM log WHERE chain = ?", (run_id,)).fetchall()
        broken = check_chain(run_id, rows)[0]
        if broken:
            return f"seq {broken[0][0]}: {broken[0][1]}"
    return None


def _format1(conn: Any, run_id: str | None) -> str | None:
    """The last entry, and every entry of the run, hashed with its seq and linked to seq - 1."""
    select = f"SELECT {_COLUMNS}, (SELECT p.hash FROM log p WHERE p.seq = l.seq - 1) FROM log l"
    rows = conn.execute(f"{select} ORDER BY seq DESC LIMIT 1").fetchall()
    if run_id is not None:
        rows += conn.execute(f"{select} WHERE run_id = ? ORDER BY seq", (run_id,)).fetchall()
    for row in rows:
        before = row[8] if row[8] is not None else (GENESIS_HASH if row[0] == 1 else None)
        if before is None:
            return f"seq {row[0] - 1} is missing (deleted rows?)"
        if not _links(row, before, row[0]):
            who = f"run {run_id}: " if row[2] == run_id and run_id is not None else ""
            return f"{who}seq {row[0]}: hash mismatch or broken link (changed after it was written)"
    return None


def _links(row: tuple[Any, ...], prev: str, number: int) -> bool:
    """The row's prev_hash is `prev` and its hash is its own (hashed with `number`)."""
    _, _, run_id, kind, payload, hash_, prev_hash, t_utc = row[:8]
    if prev_hash != prev:
        return False
    try:
        return bool(entry_hash(prev_hash, number, run_id, kind, t_utc, payload) == hash_)
    except (TypeError, ValueError):
        return False
