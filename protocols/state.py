"""A run's progress, rebuilt by folding its recorded events (so a killed run resumes exactly)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from rig.core import events as ev
from rig.core.events import RunEvent


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


@dataclass
class RunState:
    """Everything the runner needs to continue a run."""

    started: bool = False
    calibration: dict[str, Any] | None = None  # the model calibration RunStarted recorded
    finished: bool = False
    verdict: dict[str, Any] | None = None
    moi: dict[str, Any] | None = None
    environment: dict[str, Any] | None = None  # the latest lab environment check
    shots: list[ShotEntry] = field(default_factory=list)
    ball_number: int = 1
    ball_hits: int = 0
    best_location_in: float | None = None
    location_in: float | None = None
    aim_factor: float = 1.0
    extra_locations: list[float] = field(default_factory=list)  # scan extensions, in order
    invalid_at_last_check: int = 0  # invalid shots already counted when the rig was last checked
    ended: dict[str, Any] | None = None  # ended on the operator's word, no verdict

    @property
    def pending(self) -> ShotEntry | None:
        """A shot requested but never resolved: it may have been fired before a crash."""
        last = self.shots[-1] if self.shots else None
        return last if last is not None and last.valid is None and not last.lost else None

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


def fold(events: Iterable[RunEvent]) -> RunState:
    """Replay events in order into a RunState."""
    st = RunState()
    by_index: dict[int, ShotEntry] = {}
    for e in events:
        d = e.data
        if e.kind == ev.RUN_STARTED:
            st.started = True
            st.calibration = d.get("calibration")
        elif e.kind == ev.RUN_RESUMED:
            # a new session may have a repaired cannon or a corrected rig config: aim from the
            # calibration again rather than from what the last session learned
            st.aim_factor = 1.0
        elif e.kind == ev.MOI_MEASURED:
            st.moi = d
        elif e.kind == ev.ENVIRONMENT_CHECKED:
            st.environment = d
        elif e.kind == ev.LOCATION_SET:
            st.location_in = d["from_barrel_end_in"]
        elif e.kind == ev.SHOT_REQUESTED:
            entry = ShotEntry(d["index"], d["purpose"], d["location_in"])
            st.shots.append(entry)
            by_index[entry.index] = entry
        elif e.kind == ev.SHOT_FIRED:
            by_index[d["index"]].fired = True
            if d.get("crossings"):
                st.ball_hits += 1
        elif e.kind == ev.SHOT_MEASURED:
            s = by_index[d["index"]]
            s.valid, s.metric, s.measured = True, d["metric"], d
            st.aim_factor = d.get("aim_factor", st.aim_factor)
        elif e.kind == ev.SHOT_REJECTED:
            s = by_index[d["index"]]
            s.valid = False
            s.metric = d.get("metric")
            st.aim_factor = d.get("aim_factor", st.aim_factor)
        elif e.kind == ev.SHOT_OVERRULED:
            by_index[d["index"]].valid = False
        elif e.kind == ev.SHOT_LOST:
            by_index[d["index"]].lost = True
        elif e.kind == ev.BALL_REPLACED:
            st.ball_number, st.ball_hits = d["ball_number"], 0
        elif e.kind == ev.LOCATION_CHOSEN:
            st.best_location_in = d["from_barrel_end_in"]
        elif e.kind == ev.SCAN_EXTENDED:
            st.extra_locations.append(d["from_barrel_end_in"])
        elif e.kind == ev.RIG_CHECKED:
            st.invalid_at_last_check = st.invalid_count
        elif e.kind == ev.RUN_ENDED:
            st.ended = d
        elif e.kind == ev.RUN_FINISHED:
            st.finished, st.verdict = True, d
    return st
