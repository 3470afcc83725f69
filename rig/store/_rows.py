"""Row helpers of the store: a log row to a LogEntry, id checks, and the 'known ids' hint."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rig.core.errors import RecordRefused, StoreError
from rig.store._codec import decode_payload
from rig.store._records import LogEntry

ENTRY_COLUMNS = "seq, run_id, kind, payload, t_utc, prev_hash, hash, chain_seq"


def entry_from_row(row: Sequence[Any]) -> LogEntry:
    """A `log` row (ENTRY_COLUMNS order) as a LogEntry; a payload that does not decode raises StoreError."""
    seq, run_id, kind, payload, t_utc, prev_hash, hash_, chain_seq = row
    try:
        decoded = decode_payload(payload)
    except (StoreError, TypeError) as exc:  # only a tampered file gets here; verify() says more
        raise StoreError(f"seq {seq}: {exc}") from None
    return LogEntry(seq, run_id, kind, decoded, t_utc, prev_hash, hash_, chain_seq)


def check_id(name: str, value: object) -> None:
    """Refuse an id that is not a non-empty str."""
    if not isinstance(value, str) or not value.strip():
        raise RecordRefused(f"{name} {value!r}: must be a non-empty str")


def known_ids(what: str, ids: list[str], shown: int = 5) -> str:
    """'known runs: a, b, c and 2 more' (or 'there are no runs yet'), for an unknown-id message."""
    if not ids:
        return f"there are no {what} yet"
    more = f" and {len(ids) - shown} more" if len(ids) > shown else ""
    return f"known {what}: {', '.join(ids[:shown])}{more}"
