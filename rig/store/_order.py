"""Entries out of place: which ones a reordering of the log moved, in either chain format.

A reader replays a run in `seq` order (its certificate is built that way), so the order must be
the chain's. Format 1 hashes `seq`: a moved entry's own hash says where it was written. Format 2
hashes each entry's number in its chain (`chain_seq`), not `seq`: within a chain, `seq` must rise
with `chain_seq`, and the entries that break the longest rising run are the ones moved.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable
from typing import Any

from rig.store._codec import entry_hash


def out_of_place(rows: Iterable[tuple[Any, ...]]) -> list[tuple[int, str]]:
    """Format 2, one chain's rows (seq, chain_seq, ...): (seq, 'entry n: out of place: ...') for the
    fewest entries whose seq, put back, makes seq rise with chain_seq."""
    in_chain = sorted(((r[0], r[1]) for r in rows), key=lambda r: r[1])
    keep = set(_longest_rising([seq for seq, _ in in_chain]))
    by_seq = sorted(in_chain)
    seqs = [seq for seq, _ in by_seq]
    problems = []
    for i, (seq, number) in enumerate(in_chain):
        if i in keep:
            continue
        at = bisect.bisect_left(seqs, seq)
        after = f"after entry {by_seq[at - 1][1]}" if at else "first"
        chain_after = f"after entry {number - 1}" if number > 1 else "first"
        problems.append(
            (
                seq,
                f"entry {number}: out of place: the log (seq {seq}) puts it {after}, its chain "
                f"{chain_after} (entries reordered)",
            )
        )
    return problems


def hashed_seq(seq: int, candidates: Iterable[int], fields: tuple[str | None, ...]) -> int | None:
    """Format 1: the seq an entry's hash was computed with, its own or one of `candidates` (None if
    none fits: the entry was changed, not only moved). `fields`: run_id, kind, payload, t_utc,
    prev_hash, hash as stored."""
    run_id, kind, payload, t_utc, prev_hash, hash_ = fields

    def fits(n: int) -> bool:
        return entry_hash(str(prev_hash), n, run_id, str(kind), str(t_utc), str(payload)) == hash_

    if fits(seq):
        return seq
    return next((n for n in sorted(set(candidates)) if n != seq and fits(n)), None)


def _longest_rising(values: list[int]) -> list[int]:
    """Indices of one longest strictly increasing subsequence of `values` (patience sorting)."""
    tails: list[int] = []  # tails[k]: index of the smallest last value of a rising run of length k + 1
    back: list[int] = [-1] * len(values)
    for i, value in enumerate(values):
        k = bisect.bisect_left(tails, value, key=lambda t: values[t])
        back[i] = tails[k - 1] if k else -1
        if k == len(tails):
            tails.append(i)
        else:
            tails[k] = i
    chosen, i = [], tails[-1] if tails else -1
    while i >= 0:
        chosen.append(i)
        i = back[i]
    return chosen[::-1]
