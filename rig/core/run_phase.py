"""A run's phase and a shot's status: what may happen next, in two tables (docs/records.md).

The tables live here, once, in the style of the cannon's (rig.drivers.cannon.codec): the fold
(rig.core.run_state) follows them, the executor refuses an event they refuse before it is
recorded, and the store, `rig runs`, the certification's outcome, the API's result and the
console all say a run's status in their words.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from enum import StrEnum
from typing import TypeVar

from rig.core import events as ev

K = TypeVar("K")


class RunPhase(StrEnum):
    """Where a run stands in its record; str-valued, so outputs hold the words as before."""

    NEW = "new"  # created, its start not recorded
    RUNNING = "running"  # started or resumed
    INTERRUPTED = "interrupted"  # stopped, the reason recorded; resumable
    FINISHED = "finished"  # a verdict recorded
    ENDED = "ended"  # ended without a verdict: on the operator's word, or by a one-shot run's plan


class ShotStatus(StrEnum):
    """Where one requested shot stands."""

    REQUESTED = "requested"  # intent recorded, not fired
    FIRED = "fired"  # raw data recorded, outcome not yet
    VALID = "valid"
    INVALID = "invalid"  # rejected by its checks, or overruled by the operator on review
    LOST = "lost"  # it may have been fired but its outcome never came: never fired again


_N, _R, _I = RunPhase.NEW, RunPhase.RUNNING, RunPhase.INTERRUPTED
_F, _E = RunPhase.FINISHED, RunPhase.ENDED
# Set-up, shots and checks leave the phase as it is; a new run takes them too, for the executor has
# never required a plan to record its start first (the standard one does: rig.protocols.steps.start).
_IN_RUN = {_N: _N, _R: _R}
# The run table: persisted kind -> {phase it is accepted in: the phase it leads to}. Every persisted
# kind is listed; a phase not named refuses it. Live-only kinds (pauses, gate crossings) are accepted
# in every phase and change nothing: a pause holds the run, its record does not change.
RUN_TABLE: dict[str, dict[RunPhase, RunPhase]] = {
    ev.RUN_STARTED: {_N: _R, _I: _R},  # a run interrupted before it started starts when resumed
    ev.RUN_RESUMED: {_I: _R, _R: _R},  # running: a killed run, whose stop nothing recorded
    ev.INSTRUMENTS_IDENTIFIED: _IN_RUN,
    ev.ENVIRONMENT_CHECKED: _IN_RUN,
    ev.MOI_MEASURED: _IN_RUN,
    ev.OPERATOR_PROMPTED: _IN_RUN,
    ev.OPERATOR_ANSWERED: _IN_RUN,
    ev.LOCATION_SET: _IN_RUN,
    ev.SHOT_REQUESTED: _IN_RUN,
    ev.SHOT_FIRED: _IN_RUN,
    ev.SHOT_MEASURED: _IN_RUN,
    ev.SHOT_REJECTED: _IN_RUN,
    ev.SHOT_LOST: _IN_RUN,
    ev.SHOT_OVERRULED: _IN_RUN,
    ev.BALL_REPLACED: _IN_RUN,
    ev.LOCATION_CHOSEN: _IN_RUN,
    ev.SCAN_EXTENDED: _IN_RUN,
    ev.COMPRESSION_MEASURED: _IN_RUN,
    ev.BARREL_ROLLED: _IN_RUN,
    ev.ABI_STAGE_MEASURED: _IN_RUN,
    ev.RIG_CHECKED: _IN_RUN,
    ev.TRAFFIC: {_N: _N, _R: _R, _I: _I},  # whenever a session has the devices open
    ev.RUN_FINISHED: {_N: _F, _R: _F},
    ev.RUN_INTERRUPTED: {_N: _I, _R: _I, _I: _I},  # again: a resumed run whose devices would not open
    ev.RUN_ENDED: {_N: _E, _R: _E, _I: _E},
}
# A phase that accepts nothing is closed: the store seals the run there.
CLOSED = frozenset(p for p in RunPhase if not any(p in row for row in RUN_TABLE.values()))
# Where each kind leads whatever it follows (kinds whose every accepted step ends in one phase)
_LEADS_TO = {
    kind: next(iter(set(row.values()))) for kind, row in RUN_TABLE.items() if len(set(row.values())) == 1
}

_Q, _FI, _V = ShotStatus.REQUESTED, ShotStatus.FIRED, ShotStatus.VALID
# The shot table: kind -> {status it is accepted in (None: no such shot yet): the status it leads to}.
SHOT_TABLE: dict[str, dict[ShotStatus | None, ShotStatus]] = {
    ev.SHOT_REQUESTED: {None: _Q},
    ev.SHOT_FIRED: {_Q: _FI},
    ev.SHOT_MEASURED: {_FI: _V},
    ev.SHOT_REJECTED: {_FI: ShotStatus.INVALID},
    ev.SHOT_LOST: {_Q: ShotStatus.LOST, _FI: ShotStatus.LOST},  # before or after FIRE: never again
    ev.SHOT_OVERRULED: {_V: ShotStatus.INVALID},  # the operator rejects a valid shot on review
}
UNRESOLVED = frozenset({_Q, _FI})  # a shot awaiting its outcome: no other may be requested


def refuse(kind: str, phase: RunPhase) -> str | None:
    """Why the run table refuses `kind` in `phase`, or None if it accepts it (or is live-only)."""
    accepted = RUN_TABLE.get(kind)
    return (
        None if accepted is None or phase in accepted else _why(kind, f"in a run that is {phase}", accepted)
    )


def _why(kind: str, what: str, accepted: Iterable[object]) -> str:
    when = " or ".join(str(a or "not requested") for a in accepted)
    return f"no {kind} {what} (only when {when})"


def fold_step(phase: RunPhase, kind: str) -> RunPhase:
    """The phase after `kind` in a recorded log, never raising (a live run refuses first: the executor
    asks `refuse`). A damaged log's refused event leaves a closed run closed, else takes the run where
    that kind always leads (RunFinished: finished), or leaves it where it was."""
    accepted = RUN_TABLE.get(kind)
    if accepted is None:  # live only
        return phase
    after = accepted.get(phase)
    if after is not None:
        return after
    return phase if phase in CLOSED else _LEADS_TO.get(kind, phase)


def shown(phase: RunPhase, runner_alive: bool) -> RunPhase:
    """The status every output shows: running, interrupted, finished or ended. An open run is
    running only while a live runner holds it and its last stop is not an interruption."""
    if phase in CLOSED or phase is RunPhase.INTERRUPTED:
        return phase
    return RunPhase.RUNNING if runner_alive else RunPhase.INTERRUPTED


SHOWN = (RunPhase.RUNNING, RunPhase.INTERRUPTED, RunPhase.FINISHED, RunPhase.ENDED)


def shot_refuse(kind: str, status: ShotStatus | None) -> str | None:
    """Why the shot table refuses `kind` for a shot in `status`, or None (not a shot kind: None)."""
    accepted = SHOT_TABLE.get(kind)
    if accepted is None or status in accepted:
        return None
    return _why(kind, f"for a shot that is {status or 'not requested'}", accepted)


def shot_step(status: ShotStatus | None, kind: str) -> ShotStatus | None:
    """The shot's status after `kind` (unchanged if the table refuses it: a damaged log)."""
    return SHOT_TABLE.get(kind, {}).get(status, status)


def markdown() -> str:
    """Both tables in Markdown, one row per event, one column per phase (docs/records.md shows them:
    a test keeps the two the same)."""
    return f"{_grid(list(RunPhase), RUN_TABLE)}\n{_grid([None, *ShotStatus], SHOT_TABLE)}"


def _grid(columns: Sequence[K], rows: Mapping[str, Mapping[K, str]]) -> str:
    heads = ["(none)" if c is None else str(c) for c in columns]
    lines = ["| event | " + " | ".join(heads) + " |", "|---" * (len(heads) + 1) + "|"]
    for kind, row in rows.items():
        lines.append(f"| {kind} | " + " | ".join(row.get(c, "-") for c in columns) + " |")
    return "\n".join(lines) + "\n"
