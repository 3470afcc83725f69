"""The status a person is shown for a run, one word in every output (`rig runs` and its --json, the
report, the console): running, interrupted, finished or ended, the run table's words
(rig.core.run_phase.shown).

The store keeps its own words (`runs.status`: running, finished, aborted), which its schema, its
views and old files use; only what is shown differs: an ended run (stored `aborted`) is `ended`, and
an open run that nothing is running is `interrupted`.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from rig.core import events as ev
from rig.core.run_phase import SHOWN, RunPhase, shown
from rig.store import _lock

SHOWN_STATUSES: tuple[str, ...] = SHOWN
_SEALED = {"finished": RunPhase.FINISHED, "aborted": RunPhase.ENDED}


def stored_phase(stored: str, last_kind: str | None = None) -> RunPhase | None:
    """A run's phase as the store knows it without folding its log: sealed (finished or ended), or
    open: interrupted if its last entry records the interruption, else running (a run that never
    started too: its fold says new, which is shown the same). None: a word the store never writes."""
    if stored != "running":
        return _SEALED.get(stored)
    return RunPhase.INTERRUPTED if last_kind == ev.RUN_INTERRUPTED else RunPhase.RUNNING


def status_word(stored: str, last_kind: str | None = None, runner_alive: bool = False) -> str:
    """The shown word from the stored status; for an open run also its last entry's kind and whether
    a live runner holds its lock: interrupted when that entry records the interruption or no live
    runner holds it (killed, or stopped before it could record why), else running."""
    phase = stored_phase(stored, last_kind)
    return stored if phase is None else shown(phase, runner_alive)


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
