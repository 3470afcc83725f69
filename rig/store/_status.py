"""The status a person is shown for a run: the stored one, or 'interrupted' for an open run that
nothing is running (its last entry records the interruption). `rig runs` and the console's
History show the same."""

from __future__ import annotations

from typing import Any

from rig.core import events as ev


def shown_status(store: Any, run: Any) -> str:
    """'interrupted' for an open run whose last entry is its interruption, else its stored status."""
    if run.status != "running":
        return str(run.status)
    last = store.entry(run.last_seq)
    return "interrupted" if last is not None and last.kind == ev.RUN_INTERRUPTED else "running"
