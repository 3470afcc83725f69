"""rig sync: a rig's records pushed to the lab's store, run by run, verbatim.

Chain format 2 makes this possible without rewriting anything: a run's chain verifies on its own,
so its entries are copied as they are (same hashes, same times) and the target anchors the run in
its own lab chain. The source is verified before and the target after; a run whose history in the
target differs from the source's is a conflict and nothing of it is copied.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rig.core.errors import RecordRefused, StoreError
from rig.store._codec import canonical_json
from rig.store._records import COPIED_FROM, SYNCED_LAB_KINDS, LogEntry


@dataclass(frozen=True)
class SyncReport:
    """What one sync did."""

    runs_copied: int  # runs with entries added
    entries_copied: int
    runs_up_to_date: int
    bats_registered: int
    source: str
    target: str
    signatures_copied: int = 0  # RunSigned entries (and the rigs' key registrations they need)
    lab_entries_copied: int = 0  # the control charts' acknowledgements and phase I restarts

    def __str__(self) -> str:
        return (
            f"{self.source} -> {self.target}: {self.entries_copied} entries of {self.runs_copied} runs "
            f"copied, {self.runs_up_to_date} runs already up to date, {self.bats_registered} bats "
            f"registered, {self.signatures_copied} signatures copied, {self.lab_entries_copied} "
            "control-chart entries (acknowledgements, restarts) copied"
        )


def conflict(run_id: str, held: Sequence[tuple[int | None, str]], entries: Sequence[LogEntry]) -> str | None:
    """Why the target's entries of a run are not a prefix of the source's, or None."""
    if len(held) > len(entries):
        return (
            f"run {run_id}: the target holds {len(held)} entries, the source only {len(entries)}: the run "
            "went on in the target (resumed there?); refusing a conflicting history"
        )
    for (number, digest), entry in zip(held, entries, strict=False):
        if number != entry.chain_seq or digest != entry.hash:
            return (
                f"run {run_id}: entry {number} differs between the source and the target: the two "
                "histories diverged; refusing a conflicting history (nothing of this run copied)"
            )
    return None


def sync(source: Any, target: Any) -> SyncReport:
    """Copy every run of `source` missing from `target` (or its missing tail). Never rewrites either."""
    where, to = source.location, target.location
    if source.chain_format != 2:
        raise StoreError(
            f"{where}: chain format 1 (a file from before lab records): its runs cannot be copied "
            "without rewriting their hashes; it stays verifiable where it is"
        )
    checked = source.verify()
    if not checked.ok:
        raise StoreError(f"{where}: does not verify, nothing copied: {checked.problems[0]}")
    before = target.verify()
    if not before.ok:
        raise StoreError(f"{to}: does not verify, nothing copied: {before.problems[0]}")
    runs = source.runs()
    plans = []
    for run in runs:  # every conflict is found before anything is written
        entries = source.entries(run.run_id)
        held = [(e.chain_seq, e.hash) for e in _target_entries(target, run.run_id)]
        why = conflict(run.run_id, held, entries)
        if why:
            raise RecordRefused(why)
        plans.append((run, entries, len(held)))
    source_bats, target_bats = source.bats(), target.bats()
    bats = 0
    for bat_id in sorted({run.bat_id for run in runs}):
        if bat_id not in target_bats:
            target.register_bat(bat_id, source_bats[bat_id])
            bats += 1
        elif target_bats[bat_id] != source_bats[bat_id]:
            raise RecordRefused(f"bat {bat_id} is registered in {to} with other properties; nothing copied")
    copied = entries_copied = up_to_date = 0
    for run, entries, n_held in plans:
        if n_held == len(entries):
            up_to_date += 1
            continue
        entries_copied += target.import_chain(run.run_id, entries, where)
        copied += 1
    signatures = _copy_signatures(source, target, {run.run_id for run in runs})
    lab_entries = _copy_lab_entries(source, target)
    after = target.verify()
    if not after.ok:  # pragma: no cover - a bug: the copy broke what verified before
        raise StoreError(f"{to}: does not verify after the copy: {after.problems[0]}")
    return SyncReport(copied, entries_copied, up_to_date, bats, where, to, signatures, lab_entries)


def _copy_signatures(source: Any, target: Any, run_ids: set[str]) -> int:
    """The source's rig keys and run signatures the target lacks, in the source's order (a key's
    registration before the signatures it checks). Chain format 2 signs a run's own chain position,
    so a signature holds in the target as it did in the source."""
    from rig.store._signed import RIG_KEY_REGISTERED, RUN_SIGNED

    have = {
        (e.kind, canonical_json(e.payload))
        for e in target.entries(None, kinds=[RIG_KEY_REGISTERED, RUN_SIGNED])
    }
    wanted = [
        e
        for e in source.entries(None, kinds=[RIG_KEY_REGISTERED, RUN_SIGNED])
        if e.run_id is None and (e.kind == RIG_KEY_REGISTERED or e.payload.get("run_id") in run_ids)
    ]
    copied = 0
    for e in wanted:
        if (e.kind, canonical_json(e.payload)) not in have:
            target.append(None, e.kind, e.payload)
            copied += e.kind == RUN_SIGNED
    return copied


def _copy_lab_entries(source: Any, target: Any) -> int:
    """The source's control-chart entries (SYNCED_LAB_KINDS) the target lacks, in the source's order.

    The lab chain is each store's own, so an entry is appended anew; its payload keeps where and when
    it was first recorded (COPIED_FROM: the source, its seq and time there; an entry copied before
    keeps its first origin), which the charts order it by (LogEntry.recorded_utc). An entry is the
    same as one the target holds when the payloads without COPIED_FROM are.
    """

    def same(e: LogEntry) -> tuple[str, str]:
        return e.kind, canonical_json({k: v for k, v in e.payload.items() if k != COPIED_FROM})

    have = {same(e) for e in target.entries(None, kinds=list(SYNCED_LAB_KINDS)) if e.run_id is None}
    copied = 0
    for e in source.entries(None, kinds=list(SYNCED_LAB_KINDS)):
        if e.run_id is not None or same(e) in have:
            continue
        origin = e.payload.get(COPIED_FROM) or {"source": source.location, "seq": e.seq, "t_utc": e.t_utc}
        target.append(None, e.kind, {**e.payload, COPIED_FROM: origin})
        have.add(same(e))
        copied += 1
    return copied


def _target_entries(target: Any, run_id: str) -> list[LogEntry]:
    from rig.core.errors import UnknownRecord

    try:
        target.run(run_id)
    except UnknownRecord:
        return []
    entries: list[LogEntry] = target.entries(run_id)
    return entries
