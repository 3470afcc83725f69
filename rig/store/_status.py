"""The status a person is shown for a run, one word in every output (`rig runs` and its --json, the
report, the console): running, interrupted, finished or ended.

The store keeps its own words (`runs.status`: running, finished, aborted), which its schema, its
views and old files use; only what is shown differs: an ended run (stored `aborted`) is `ended`, and
an open run that nothing is running is `interrupted`.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from rig.core import events as ev
from rig.store import _lock

SHOWN_STATUSES = ("running", "interrupted", "finished", "ended")
_SEALED = {"finished": "finished", "aborted": "ended"}


def status_word(stored: str, last_kind: str | None = None, runner_alive: bool = False) -> str:
    """The shown word from the stored status; for an open run also its last entry's kind and whether
    a live runner holds its lock: interrupted when that entry records the interruption or no live
    runner holds it (killed, or stopped before it could record why), else running."""
    if stored != "running":
        return _SEALED.get(stored, stored)
    return "running" if runner_alive and last_kind != ev.RUN_INTERRUPTED else "interrupted"


def runner_alive(lock: _lock.RunLock | None) -> bool:
    """Whether a run lock row names a runner that may still be running (not stale)."""
    return lock is not None and _lock.stale_reason(lock, datetime.now(UTC)) is None


def shown_status(store: Any, run: Any) -> str:
    """The word shown for `run` (a RunSummary of `store`)."""
    if run.status != "running":
        return status_word(str(run.status))
    last = store.entry(run.last_seq)
    alive = runner_alive(store.run_lock_holder(run.run_id))
    return status_word("running", last.kind if last is not None else None, alive)
