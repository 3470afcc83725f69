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
from rig.core.outcomes import MoiResult, RunVerdict, ShotOutcome
from rig.core.run_phase import UNRESOLVED, RunPhase, ShotStatus, fold_step


@dataclass
class ShotEntry:
    """What the record says about one requested shot: the one shot type the fold, the report, the
    console and the views read. The request, the raw record (ShotFired) and the evaluation
    (ShotOutcome) are kept apart, as the log has them."""

    index: int
    purpose: str  # "scan" or "valid"
    location_in: float
    requested: ev.ShotRequested | None = None
    requested_utc: str | None = None
    raw: ev.ShotFired | None = None  # the raw record, before anything was derived
    outcome: ShotOutcome | None = None  # the evaluation: speeds, metrics, u, validity
    overruled: list[ev.ShotOverruled] = field(default_factory=list)  # the operator's rejections
    lost: bool = False
    lost_reason: str | None = None

    @property
    def fired(self) -> bool:
        """Whether its raw record was recorded."""
        return self.raw is not None

    @property
    def valid(self) -> bool | None:
        """Valid, invalid (rejected, overruled or lost), or None until evaluated."""
        if self.overruled or self.lost:
            return False
        return None if self.outcome is None else self.outcome.valid

    @property
    def metric(self) -> float | None:
        """The evaluated metric (None before evaluation, or if it could not be computed)."""
        return None if self.outcome is None else self.outcome.metric

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
    verdict: RunVerdict | None = None
    moi: MoiResult | None = None
    environment: dict[str, Any] | None = None  # the latest lab environment check (its payload)
    environment_checks: list[Noted] = field(default_factory=list)
    instruments: list[Noted] = field(default_factory=list)  # each session's identification
    operator: list[Noted] = field(default_factory=list)  # prompts and answers, in order
    stops: list[Noted] = field(default_factory=list)  # interruptions, resumptions, rig checks, the end
    scan_extensions: list[Noted] = field(default_factory=list)
    shots: list[ShotEntry] = field(default_factory=list)
    by_index: dict[int, ShotEntry] = field(default_factory=dict)
    ball_number: int = 1
    ball_hits: int = 0
    location: ev.LocationChosen | None = None
    location_in: float | None = None
    aim_factor: float = 1.0
    aim_shots: int = 0  # shots that taught aim_factor since the run (or its last resume) started
    extra_locations: list[float] = field(default_factory=list)  # scan extensions, in order
    invalid_at_last_check: int = 0  # invalid shots already counted when the rig was last checked
    ended: ev.RunEnded | None = None  # ended on the operator's word, no verdict
    abi: list[Noted] = field(default_factory=list)  # an accelerated break-in's record, in order

    @property
    def finished(self) -> bool:
        """Whether a verdict is recorded (the run table's finished phase)."""
        return self.phase is RunPhase.FINISHED

    @property
    def best_location_in(self) -> float | None:
        """The location chosen for the valid hits (None before the scan chose one)."""
        return None if self.location is None else self.location.from_barrel_end_in

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
        return sum(1 for s in self.shots if s.valid is False)

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
        noted = Noted(e.kind, e.data, t_utc, seq)
        match e:
            case ev.RunStarted():
                self.started, self.setup, self.calibration = True, e.data, e.calibration
            case ev.RunResumed():
                # a new session may have a repaired cannon or a corrected rig config: aim from the
                # calibration again rather than from what the last session learned
                self.aim_factor, self.aim_shots = 1.0, 0
            case ev.InstrumentsIdentified():
                self.instruments.append(noted)
            case ev.MoiMeasured():
                self.moi = e.result
            case ev.EnvironmentChecked():
                self.environment = e.data
                self.environment_checks.append(noted)
            case ev.OperatorPrompted() | ev.OperatorAnswered():
                self.operator.append(noted)
            case ev.LocationSet():
                self.location_in = e.from_barrel_end_in
            case ev.ShotRequested():
                entry = ShotEntry(e.index, e.purpose, e.location_in, requested=e, requested_utc=t_utc)
                self.shots.append(entry)
                self.by_index[entry.index] = entry
            case ev.ShotFired():
                self._shot(e.index).raw = e
                if e.crossings:
                    self.ball_hits += 1
            case ev.ShotEvaluated():
                self._shot(e.index).outcome = o = e.outcome
                self.aim_factor = self.aim_factor if o.aim_factor is None else o.aim_factor
                self.aim_shots = self.aim_shots if o.aim_shots is None else o.aim_shots
            case ev.ShotOverruled():
                self._shot(e.index).overruled.append(e)
            case ev.ShotLost():
                shot = self._shot(e.index)
                shot.lost, shot.lost_reason = True, e.reason or ""
            case ev.BallReplaced():
                self.ball_number, self.ball_hits = e.ball_number, 0
            case ev.LocationChosen():
                self.location = e
            case ev.ScanExtended():
                self.extra_locations.append(e.from_barrel_end_in)
                self.scan_extensions.append(noted)
            case ev.RunFinished():
                self.verdict = e.result
            case ev.RigChecked():
                self.invalid_at_last_check = self.invalid_count
            case ev.RunEnded():
                self.ended = e
        if e.kind in ev.STOP_KINDS:
            self.stops.append(noted)
        if e.kind in ev.ABI_KINDS or (
            isinstance(e, ev.OperatorAnswered) and e.prompt_id.startswith(ev.ABI_DAMAGE_PROMPT)
        ):
            self.abi.append(noted)


def fold(events: Iterable[RunEvent]) -> RunState:
    """Replay events in order into a RunState."""
    st = RunState()
    for e in events:
        st.apply(e)
    return st
