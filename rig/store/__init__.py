"""Run records: an append-only, hash-chained log, in SQLite (WAL) or PostgreSQL, with tables derived from it.

The log is the record of truth (rule 5, "nothing is lost"); `bats` and `runs` are conveniences
rebuilt from it at will. See docs/records.md for the schema, the chain and its limits.
"""

from rig.core.errors import RecordRefused, StoreError, StoreFileError, UnknownRecord
from rig.store._codec import GENESIS_HASH, canonical_json, decode_bytes, encode_bytes, entry_hash
from rig.store._guard import StoreGone
from rig.store._integrity import StoreDamaged
from rig.store._lock import RunLock, RunLocked
from rig.store._pg import is_url, safe_url
from rig.store._records import (
    RESERVED_KINDS,
    RUN_CREATED,
    RUN_STATUSES,
    Anchor,
    LogEntry,
    RunStatus,
    RunSummary,
    VerifyReport,
)
from rig.store._schema import SCHEMA_VERSION
from rig.store._signed import run_seal
from rig.store._status import SHOWN_STATUSES, shown_status, status_word
from rig.store._store import DEFAULT_LEASE_S, EntrySpec, Store
from rig.store._writer import RunWriter

__all__ = [
    "DEFAULT_LEASE_S",
    "GENESIS_HASH",
    "RESERVED_KINDS",
    "RUN_CREATED",
    "RUN_STATUSES",
    "SCHEMA_VERSION",
    "SHOWN_STATUSES",
    "Anchor",
    "EntrySpec",
    "LogEntry",
    "RecordRefused",
    "RunLock",
    "RunLocked",
    "RunStatus",
    "RunSummary",
    "RunWriter",
    "Store",
    "StoreDamaged",
    "StoreError",
    "StoreFileError",
    "StoreGone",
    "UnknownRecord",
    "VerifyReport",
    "canonical_json",
    "decode_bytes",
    "encode_bytes",
    "entry_hash",
    "is_url",
    "run_seal",
    "safe_url",
    "shown_status",
    "status_word",
]
