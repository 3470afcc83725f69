"""Chain format 2: one hash chain per run plus the lab chain, and the lab chain's run anchors.

Each run's entries chain from genesis in their own order (`chain_seq`), so rigs appending to
one database never wait for each other, and a run's records verify on their own wherever they
are copied. The lab chain holds the entries of no run (bats) and, for each run, a RunOpened
anchor (the hash of its first entry) and a RunSealed anchor (its last entry when it closed):
a run deleted whole, or cut or extended after its seal, is found from the lab chain.
"""

from __future__ import annotations

import json
from typing import Any

from rig.store._codec import GENESIS_HASH, entry_hash
from rig.store._order import out_of_place
from rig.store._records import LAB_CHAIN, RUN_OPENED, RUN_SEALED, RUN_STATUS_CHANGED, Anchor

# one row: (global seq, chain_seq, run_id, kind, payload, hash, prev_hash, t_utc)
Row = tuple[int, int, str | None, str, str, str, str, str]


class Chains:
    """Collects each chain's readable rows as the verifier walks the log."""

    def __init__(self) -> None:
        self.rows: dict[str, list[Row]] = {}
        self.problems: list[tuple[int, str]] = []

    def feed(self, seq: int, chain: object, chain_seq: object, fields: tuple[Any, ...]) -> None:
        """Take one row whose text columns decoded (run_id, kind, payload, t_utc, prev, hash)."""
        run_id, kind, payload, t_utc, prev_hash, hash_ = fields
        want: str = run_id if run_id is not None else LAB_CHAIN
        if chain != want or not isinstance(chain_seq, int):
            self.problems.append(
                (seq, f"chain columns ({chain!r}, {chain_seq!r}) do not belong to its run {run_id!r}")
            )
            return
        self.rows.setdefault(want, []).append(
            (seq, chain_seq, run_id, kind, payload, hash_, prev_hash, t_utc)
        )


def check_chain(name: str, rows: list[Row]) -> tuple[list[tuple[int, str]], Anchor | None]:
    """One chain: numbered from 1 without gaps, each entry linked to the one before, its own hash."""
    problems: list[tuple[int, str]] = []
    expected, prev = 1, GENESIS_HASH
    for seq, number, run_id, kind, payload, hash_, prev_hash, t_utc in sorted(rows, key=lambda r: r[1]):
        where = f"{_chain_words(name)} entry {number}"
        if number != expected:
            missing = f"{expected}" if number == expected + 1 else f"{expected}..{number - 1}"
            problems.append((seq, f"{_chain_words(name)}: entry {missing} missing (deleted rows?)"))
        elif prev_hash != prev:
            problems.append(
                (
                    seq,
                    f"{where}: prev_hash mismatch: does not link to the entry before it "
                    "(an entry was inserted, removed, reordered or re-hashed)",
                )
            )
        elif entry_hash(prev_hash, number, run_id, kind, t_utc, payload) != hash_:
            problems.append((seq, f"{where}: hash mismatch: the entry was changed after it was written"))
        expected, prev = number + 1, hash_
    problems += [(seq, f"{_chain_words(name)} {text}") for seq, text in out_of_place(rows)]
    last = max(rows, key=lambda r: r[1]) if rows else None
    return problems, (Anchor(last[0], last[5]) if last else None)


def check_anchors(chains: dict[str, list[Row]], only: str | None = None) -> list[str]:
    """Every run chain is anchored in the lab chain where it opened and, once sealed, where it closed
    (`only`: the one run whose chain was read, with the lab chain)."""
    opened: dict[str, str] = {}
    sealed: dict[str, tuple[int, str]] = {}
    for _, _, _, kind, payload, *_ in chains.get(LAB_CHAIN, []):
        if kind in (RUN_OPENED, RUN_SEALED):
            data = _payload(payload)
            run_id = data.get("run_id")
            if kind == RUN_OPENED:
                opened[str(run_id)] = str(data.get("hash"))
            else:
                sealed[str(run_id)] = (int(data.get("chain_seq") or 0), str(data.get("hash")))
    problems = []
    for run_id, rows in chains.items():
        if run_id == LAB_CHAIN or (only is not None and run_id != only):
            continue
        by_number = {r[1]: r for r in rows}
        first, last = by_number.get(1), max(rows, key=lambda r: r[1])
        if run_id not in opened:
            problems.append(
                f"run {run_id}: not anchored in the lab chain (no RunOpened): added from outside?"
            )
        elif first is None or first[5] != opened[run_id]:
            problems.append(f"run {run_id}: its first entry is not the one the lab chain anchored")
        closed = any(r[3] == RUN_STATUS_CHANGED for r in rows)
        if run_id in sealed:
            number, digest = sealed[run_id]
            at = by_number.get(number)
            if at is None or at[5] != digest:
                problems.append(
                    f"run {run_id}: its sealed entry {number} is not the one the lab chain anchored"
                )
            elif last[1] != number:
                problems.append(f"run {run_id}: {last[1] - number} entries after its seal (entry {number})")
        elif closed:
            problems.append(f"run {run_id}: closed, but its seal is not anchored in the lab chain")
    for run_id in sorted(set(opened) - set(chains)):
        if only is not None and run_id != only:
            continue
        problems.append(f"run {run_id}: anchored in the lab chain but its entries are gone")
    return problems


def _chain_words(name: str) -> str:
    return "the lab chain" if name == LAB_CHAIN else f"run {name}"


def _payload(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}
