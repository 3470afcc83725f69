"""A run's entries on their way to the store: held until the next commit point, then one transaction.

Every commit of a SQLite store is forced to disk (synchronous=FULL), a few milliseconds each; a run
that committed each entry alone spent most of its time there. A RunWriter holds the entries that
may wait and writes them, in order, in the transaction of the next entry that may not
(`Store.append_many`: all or none). What may wait is the caller's word (rig.core.events: `commits`):
what a resumed run makes again, and a shot's raw record until its outcome. So the log on disk is
always a prefix of what the run recorded, and a crash loses only the entries after the last commit
point (docs/records.md, "Commit points").
"""

from __future__ import annotations

import json
from typing import Any

from rig.core.errors import RecordRefused
from rig.store._codec import check_kind, check_payload
from rig.store._records import RESERVED_KINDS, LogEntry
from rig.store._store import EntrySpec, Store


class RunWriter:
    """Writes one run's entries to `store`, each commit point with the entries held before it."""

    def __init__(self, store: Store, run_id: str) -> None:
        self.store, self.run_id = store, run_id
        self._held: list[EntrySpec] = []

    @property
    def held(self) -> int:
        """How many entries wait for the next commit point."""
        return len(self._held)

    def record(self, kind: str, payload: dict[str, Any], *, commit: bool = True) -> list[LogEntry]:
        """Take one entry; with `commit`, write it and every held one in one transaction (returned),
        else hold it ([]). A kind or payload the store would refuse is refused here, at once."""
        if check_kind(kind) in RESERVED_KINDS:
            raise RecordRefused(f"kind {kind} is written by the store itself; use its own method")
        # checked now, and copied: a caller changing its dict afterwards cannot change the entry
        self._held.append((self.run_id, kind, json.loads(check_payload(payload))))
        return self.commit() if commit else []

    def commit(self) -> list[LogEntry]:
        """Write the held entries in one transaction ([] if none). If the store fails or refuses it
        (gone, full, the run's lock lost), the error is raised and the entries are let go, as a crash
        there would lose them: never written twice (a commit that did land before an interruption
        cannot be retried), and the run stops (its interruption, if it can be written, comes next)."""
        held, self._held = self._held, []
        return self.store.append_many(held) if held else []
