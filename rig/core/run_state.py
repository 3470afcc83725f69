"""A run's facts, rebuilt by folding its events: the one fold of the log.

The runner resumes from it (a killed run resumes exactly), the report renders it and the console
starts from it. Events may come with their log entry's time and sequence number (`apply`), which
the record shows; the runner's own fold goes without.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from rig.core import events as ev
from rig.core.events import RunEvent
from rig.core.run_phase import UNRESOLVED, RunPhase, ShotStatus, fold_step


@dataclass
class ShotEntry:
    """What the record says about one requested shot."""

    index: int
    purpose: str  # "scan" or "valid"
    location_in: float
    fired: bool = False
    valid: bool | None = None  # None until measured or rejected
    metric: float | None = None
    lost: bool = False
    measured: dict[str, Any] = field(default_factory=dict)
    requested: dict[str, Any] = field(default_factory=dict)  # the ShotRequested payload
    requested_utc: str | None = None
    raw: dict[str, Any] | None = None  # the ShotFired payload
    outcome: dict[str, Any] | None = None  # the ShotMeasured or ShotRejected payload
    overruled: list[dict[str, Any]] = field(default_factory=list)  # ShotOverruled payloads
    lost_reason: str | None = None

    @property
    def status(self) -> ShotStatus:
        """requested | fired | valid | invalid | lost (rig.core.run_phase.SHOT_TABLE)."""
        if self.lost:
            return ShotStatus.LOST
        if self.valid is not None:
            return ShotStatus.VALID if self.valid else ShotStatus.INVALID
        return ShotStatus.FIRED if self.fired else ShotStatus.REQUESTED


@dataclass(frozen=True)
class Noted:
    """An event's payload with where the log put it (time, sequence number; None if not from the log)."""

    kind: str
    data: dict[str, Any]
    t_utc: str | None = None
    seq: int | None = None


@dataclass
class RunState:
    """Everything known about a run from its events."""

    phase: RunPhase = RunPhase.NEW  # by the run table (rig.core.run_phase)
    started: bool = False
    setup: dict[str, Any] | None = None  # the RunStarted payload: procedure, bat, rig, software
    calibration: dict[str, Any] | None = None  # the model calibration RunStarted recorded
    finished: bool = False
    verdict: dict[str, Any] | None = None
    moi: dict[str, Any] | None = None
    environment: dict[str, Any] | None = None  # the latest lab environment check
    environment_checks: list[Noted] = field(default_factory=list)
    instruments: list[Noted] = field(default_factory=list)  # each session's identification
    operator: list[Noted] = field(default_factory=list)  # prompts and answers, in order
    stops: list[Noted] = field(default_factory=list)  # interruptions, resumptions, rig checks, the end
    scan_extensions: list[Noted] = field(default_factory=list)
    shots: list[ShotEntry] = field(default_factory=list)
    by_index: dict[int, ShotEntry] = field(default_factory=dict)
    ball_number: int = 1
    ball_hits: int = 0
    location: dict[str, Any] | None = None  # the LocationChosen payload
    best_location_in: float | None = None
    location_in: float | None = None
    aim_factor: float = 1.0
    aim_shots: int = 0  # shots that taught aim_factor since the run (or its last resume) started
    extra_locations: list[float] = field(default_factory=list)  # scan extensions, in order
    invalid_at_last_check: int = 0  # invalid shots already counted when the rig was last checked
    ended: dict[str, Any] | None = None  # ended on the operator's word, no verdict

    @property
    def pending(self) -> ShotEntry | None:
        """A shot requested but never resolved: it may have been fired before a crash."""
        last = self.shots[-1] if self.shots else None
        return last if last is not None and last.status in UNRESOLVED else None

    def valid_shots(self, purpose: str, location_in: float | None = None) -> list[ShotEntry]:
        """Valid shots of a purpose (at a location)."""
        return [
            s
            for s in self.shots
            if s.purpose == purpose and s.valid and (location_in is None or s.location_in == location_in)
        ]

    @property
    def invalid_count(self) -> int:
        """Shots rejected or lost."""
        return sum(1 for s in self.shots if s.valid is False or s.lost)

    @property
    def invalid_since_check(self) -> int:
        """Shots rejected or lost since the operator last confirmed the rig was checked."""
        return self.invalid_count - self.invalid_at_last_check

    def scan_locations(self, planned: list[float]) -> list[float]:
        """The procedure's scan locations and the extensions recorded so far, in scan order."""
        return planned + [x for x in self.extra_locations if x not in planned]

    def _shot(self, index: int) -> ShotEntry:
        shot = self.by_index.get(index)
        if shot is None:  # an outcome with no request: only a damaged log has one
            shot = self.by_index[index] = ShotEntry(index, "", float("nan"))
        return shot

    def apply(self, e: RunEvent, t_utc: str | None = None, seq: int | None = None) -> None:
        """Take one event (live-only ones change nothing)."""
        self.phase = fold_step(self.phase, e.kind)
        d, kind = e.data, e.kind
        noted = Noted(kind, d, t_utc, seq)
        if kind == ev.RUN_STARTED:
            self.started, self.setup = True, d
            self.calibration = d.get("calibration")
        elif kind == ev.RUN_RESUMED:
            # a new session may have a repaired cannon or a corrected rig config: aim from the
            # calibration again rather than from what the last session learned
            self.aim_factor, self.aim_shots = 1.0, 0
        elif kind == ev.INSTRUMENTS_IDENTIFIED:
            self.instruments.append(noted)
        elif kind == ev.MOI_MEASURED:
            self.moi = d
        elif kind == ev.ENVIRONMENT_CHECKED:
            self.environment = d
            self.environment_checks.append(noted)
        elif kind in (ev.OPERATOR_PROMPTED, ev.OPERATOR_ANSWERED):
            self.operator.append(noted)
        elif kind == ev.LOCATION_SET:
            self.location_in = d["from_barrel_end_in"]
        elif kind == ev.SHOT_REQUESTED:
            entry = ShotEntry(d["index"], d["purpose"], d["location_in"], requested=d, requested_utc=t_utc)
            self.shots.append(entry)
            self.by_index[entry.index] = entry
        elif kind == ev.SHOT_FIRED:
            shot = self._shot(d["index"])
            shot.fired, shot.raw = True, d
            if d.get("crossings"):
                self.ball_hits += 1
        elif kind in (ev.SHOT_MEASURED, ev.SHOT_REJECTED):
            shot = self._shot(d["index"])
            shot.valid, shot.metric, shot.outcome = kind == ev.SHOT_MEASURED, d.get("metric"), d
            if shot.valid:
                shot.measured = d
            self.aim_factor = d.get("aim_factor", self.aim_factor)
            self.aim_shots = d.get("aim_shots", self.aim_shots)
        elif kind == ev.SHOT_OVERRULED:
            shot = self._shot(d["index"])
            shot.valid = False
            shot.overruled.append(d)
        elif kind == ev.SHOT_LOST:
            shot = self._shot(d["index"])
            shot.lost, shot.lost_reason = True, d.get("reason", "")
        elif kind == ev.BALL_REPLACED:
            self.ball_number, self.ball_hits = d["ball_number"], 0
        elif kind == ev.LOCATION_CHOSEN:
            self.location, self.best_location_in = d, d["from_barrel_end_in"]
        elif kind == ev.SCAN_EXTENDED:
            self.extra_locations.append(d["from_barrel_end_in"])
            self.scan_extensions.append(noted)
        elif kind == ev.RUN_FINISHED:
            self.finished, self.verdict = True, d
        if kind in ev.STOP_KINDS:
            self.stops.append(noted)
            if kind == ev.RIG_CHECKED:
                self.invalid_at_last_check = self.invalid_count
            elif kind == ev.RUN_ENDED:
                self.ended = d


def fold(events: Iterable[RunEvent]) -> RunState:
    """Replay events in order into a RunState."""
    st = RunState()
    for e in events:
        st.apply(e)
    return st
