"""What the store hands out: frozen records read from the log and the convenience tables."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Literal

from rig.core.errors import RecordRefused
from rig.core.events import CHECK_ACKNOWLEDGED, CHECK_RESTARTED

_HEX64 = re.compile(r"[0-9a-fA-F]{64}")

RunStatus = Literal["running", "finished", "aborted"]
RUN_STATUSES: tuple[str, ...] = ("running", "finished", "aborted")

# Kinds the store writes itself; append() refuses them so the tables always follow the log.
BAT_REGISTERED = "BatRegistered"
RUN_CREATED = "RunCreated"
RUN_STATUS_CHANGED = "RunStatusChanged"
RUN_LOCK_BROKEN = "RunLockBroken"  # a stale runner's lock was broken by the next runner
# Chain format 2: the lab chain anchors each run's chain when it opens and when it is sealed.
RUN_OPENED = "RunOpened"
RUN_SEALED = "RunSealed"
RUN_SYNCED = "RunSynced"  # rig sync copied entries of a run from another store
BALL_LOT_REGISTERED = "BallLotRegistered"  # lab-level: a ball lot (rig balls register)
BALL_LAW_RECORDED = "BallLawRecorded"  # lab-level: a lot's fitted ball law (rig model fit-ball --db --lot)
# Lab-level entries of the check standard's charts (rig.quality) that rig sync carries to the lab's store
SYNCED_LAB_KINDS = (CHECK_ACKNOWLEDGED, CHECK_RESTARTED)
COPIED_FROM = "copied_from"  # in such an entry rig sync copied: where and when it was first recorded
RESERVED_KINDS = frozenset(
    {
        BAT_REGISTERED,
        RUN_CREATED,
        RUN_STATUS_CHANGED,
        RUN_LOCK_BROKEN,
        RUN_OPENED,
        RUN_SEALED,
        RUN_SYNCED,
        BALL_LOT_REGISTERED,
        BALL_LAW_RECORDED,
    }
)
LAB_CHAIN = "lab"  # format 2: the chain of entries that belong to no run (bats, run anchors)
CLOSED_STATUSES: tuple[str, ...] = ("finished", "aborted")  # a run in one of these is sealed


@dataclass(frozen=True)
class LogEntry:
    """One entry of the append-only log, payload decoded (a fresh dict on every read)."""

    seq: int
    run_id: str | None
    kind: str
    payload: dict[str, Any]
    t_utc: str
    prev_hash: str
    hash: str
    chain_seq: int | None = None  # format 2: the entry's number in its chain (its run's, or the lab's)

    @property
    def time(self) -> datetime:
        """t_utc as an aware datetime."""
        return datetime.fromisoformat(self.t_utc)

    @property
    def recorded_utc(self) -> str:
        """When the entry was first recorded: t_utc, or for a lab-level entry rig sync copied from a
        rig's store, the time it had there."""
        copied = self.payload.get(COPIED_FROM)
        first = copied.get("t_utc") if isinstance(copied, dict) else None
        return first if isinstance(first, str) else self.t_utc


@dataclass(frozen=True)
class RunSummary:
    """One row of the `runs` table: where a run stands, derived from the log."""

    run_id: str
    procedure: str
    bat_id: str
    started_utc: str
    status: RunStatus
    verdict: str | None
    last_seq: int


@dataclass(frozen=True)
class Anchor:
    """A (seq, hash) pair kept outside the file, e.g. printed on a certificate."""

    seq: int
    hash: str

    @classmethod
    def parse(cls, text: str) -> Anchor:
        """'SEQ:HASH' as printed on a certificate; anything else raises RecordRefused."""
        seq, colon, digest = text.strip().partition(":")
        number = int(seq) if seq.isascii() and seq.isdigit() and len(seq) <= 19 else 0
        if not (colon and 1 <= number < 2**63 and _HEX64.fullmatch(digest)):
            raise RecordRefused(
                f"anchor {text!r}: expected SEQ:HASH as printed on a certificate "
                "(an entry number from 1, a colon, then 64 hex digits)"
            )
        return cls(number, digest.lower())

    def __str__(self) -> str:
        return f"{self.seq}:{self.hash}"


@dataclass(frozen=True)
class VerifyReport:
    """Outcome of `Store.verify()`; `problems` lists every finding, chain ones first."""

    ok: bool
    entries_checked: int
    head: Anchor
    first_broken_seq: int | None = None
    reason: str | None = None
    problems: tuple[str, ...] = field(default=())
    runs_signed: int = 0  # sealed runs whose RunSigned holds (rig.store._signed)
    runs_unsigned: int = 0
    runs_bad_signature: int = 0
    unlisted_signatures: tuple[str, ...] = ()  # per unsigned run signed by an unregistered key: its rig

    def __str__(self) -> str:
        if self.ok:
            return f"ok: {self.entries_checked} entries, head seq {self.head.seq} hash {self.head.hash}"
        return "BROKEN: " + "; ".join(self.problems)
