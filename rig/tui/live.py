"""What the run screen shows, from the run's events (pure: no Textual, no devices).

The facts (shots' outcomes, MOI, location, verdict) come from the one fold of the log
(rig.core.run_state), which LiveRun keeps; on top of it go what only a live run has: speeds as
soon as known, gate ticks as they come, pauses and the log lines. A resumed run starts from its
recorded events, so the scan, the hits and the average are whole again before the first new shot.
"""

from __future__ import annotations

import base64
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from rig.core import events as ev
from rig.core.devices import CannonStatus, GateConfig
from rig.core.events import RunEvent
from rig.core.outcomes import RunVerdict
from rig.core.run_state import RunState, ShotEntry
from rig.protocols.procedure import Procedure


@dataclass
class LiveShot:
    """The shot in progress or the last one: the fold's record of it (the one shot type, shared with
    the runner and the report) and what only a live run sees, speeds as soon as known and the ticks."""

    entry: ShotEntry
    inbound: float | None = None
    rebound: float | None = None
    crossings: list[tuple[int, int]] = field(default_factory=list)  # (gate, tick) as they came

    @property
    def index(self) -> int:
        return self.entry.index

    @property
    def purpose(self) -> str:
        return self.entry.purpose

    @property
    def location_in(self) -> float | None:
        return float(self.entry.location_in) if self.entry.requested else None

    @property
    def status(self) -> str:
        """requested | fired | valid | invalid | lost."""
        return self.entry.status

    @property
    def metric(self) -> float | None:
        return self.entry.metric

    @property
    def u(self) -> float | None:
        return None if self.entry.outcome is None else self.entry.outcome.u

    @property
    def reasons(self) -> list[str]:
        """Why the shot does not count, as lines."""
        e = self.entry
        if e.lost:
            return [str(e.lost_reason)]
        if e.overruled:
            return [f"OPERATOR_REJECTED: {e.overruled[-1].reason or ''}"]
        found = [] if e.outcome is None else e.outcome.reasons
        return [f"{x['code']}: {x.get('message', '')}" for x in found if x.get("invalidates", True)]


TRAFFIC_LINES = 60


@dataclass
class LiveRun:
    """The state of the run screen."""

    metric_name: str = ""
    limit: float | None = None
    scan_locations: list[float] = field(default_factory=list)
    hits_needed: int = 0
    cannon: CannonStatus | None = None
    cannon_error: str = ""
    cannon_note: str = ""  # why the status is unknown now (the run ended: the rig vented, nothing read)
    gate_config: GateConfig | None = None
    pressure_kpa: float | None = None  # at the last shot
    environment: str = ""
    moi: float | None = None
    shot: LiveShot | None = None
    shots: dict[int, LiveShot] = field(default_factory=dict)
    best_location_in: float | None = None
    prediction: float | None = None
    prediction_note: str = ""
    verdict: RunVerdict | None = None
    interrupted: str = ""
    paused: bool = False
    log: list[str] = field(default_factory=list)
    traffic: deque[str] = field(default_factory=lambda: deque(maxlen=TRAFFIC_LINES))  # decoded lines
    _partial: dict[tuple[str, str], str] = field(default_factory=dict)  # a line not yet ended
    run: RunState = field(default_factory=RunState)  # the fold of the persisted events

    # -- derived views ------------------------------------------------------------------------
    def scan_means(self) -> dict[float, float]:
        """Mean metric of the valid scan shots at each location so far."""
        acc: dict[float, list[float]] = {}
        for s in self.shots.values():
            if s.purpose == "scan" and s.status == "valid" and s.metric is not None:
                acc.setdefault(s.location_in or 0.0, []).append(s.metric)
        return {loc: sum(v) / len(v) for loc, v in sorted(acc.items())}

    def hits(self) -> list[float]:
        """The valid hits at the chosen location, in order."""
        return [
            s.metric
            for _, s in sorted(self.shots.items())
            if s.purpose == "valid" and s.status == "valid" and s.metric is not None
        ]

    def average(self) -> float | None:
        """The running average of the valid hits."""
        hits = self.hits()
        return sum(hits) / len(hits) if hits else None

    def set_procedure(self, p: Procedure) -> None:
        """Take the metric, the limit, the scan and the number of hits from the procedure."""
        self.metric_name, self.limit = p.standard, p.limit
        self.scan_locations, self.hits_needed = p.scan.locations_in(), p.hits.valid_hits

    # -- the fold -----------------------------------------------------------------------------
    def apply(self, event: RunEvent) -> None:
        """Update from one event (live or recorded)."""
        d, kind = event.data, event.kind
        if kind in ev.PERSISTED:
            self.run.apply(event)
        handler = _HANDLERS.get(kind)
        if handler is not None:
            handler(self, d)

    def _shot(self, index: int) -> LiveShot:
        """The shot on screen, backed by the fold's entry once the shot is requested."""
        entry = self.run.by_index.get(index)
        shot = self.shots.get(index)
        if shot is None:
            shot = self.shots[index] = LiveShot(entry or ShotEntry(index, "", math.nan))
        elif entry is not None:
            shot.entry = entry
        self.shot = shot
        return shot

    def note(self, line: str) -> None:
        """Add a line to the run's log."""
        self.log.append(line)


def _started(r: LiveRun, d: dict[str, Any]) -> None:
    p = Procedure.model_validate(d["procedure"])
    r.set_procedure(p)
    r.note(f"{p.name} on bat {d['bat']['id']}")


def _rig_named(r: LiveRun, d: dict[str, Any]) -> None:
    rig = f"rig {d['name']}" + (" (simulated)" if d["simulated"] else "")
    r.note(rig + (f": {d['signing']}" if d["signing"] else ""))


def _resumed(r: LiveRun, d: dict[str, Any]) -> None:
    r.interrupted = ""
    r.note(f"resumed after {d['shots_so_far']} shot(s)")


def _environment(r: LiveRun, d: dict[str, Any]) -> None:
    r.environment = f"{d['temperature_c']:.1f} C, {d['humidity_pct']:.0f} % RH" + (
        "" if d["ok"] else " OUT OF LIMITS"
    )
    r.note(f"lab {r.environment}")


def _moi(r: LiveRun, d: dict[str, Any]) -> None:
    moi = r.run.moi
    assert moi is not None, "the fold took the MoiMeasured first"
    r.moi = float(moi.moi_kgm2)
    r.note(f"MOI {r.moi:.5f} kg m^2 ({moi.source})")


def _requested(r: LiveRun, d: dict[str, Any]) -> None:
    r._shot(int(d["index"]))


def _crossed(r: LiveRun, d: dict[str, Any]) -> None:
    r._shot(int(d["index"])).crossings.append((int(d["gate"]), int(d["tick"])))


def _inbound(r: LiveRun, d: dict[str, Any]) -> None:
    r._shot(int(d["index"])).inbound = float(d["speed_m_s"])


def _rebound(r: LiveRun, d: dict[str, Any]) -> None:
    r._shot(int(d["index"])).rebound = float(d["speed_m_s"])


def _fired(r: LiveRun, d: dict[str, Any]) -> None:
    shot = r._shot(int(d["index"]))
    if not shot.crossings:  # a recorded shot (resume): the raw ticks stand in for the live ones
        shot.crossings = [(int(c["gate"]), int(c["tick"])) for c in d.get("crossings", [])]
    if d.get("pressure_kpa") is not None:
        r.pressure_kpa = float(d["pressure_kpa"])
    if isinstance(d.get("gate_config"), dict):
        r.gate_config = GateConfig(**d["gate_config"])


def _measured(r: LiveRun, d: dict[str, Any]) -> None:
    shot = r._shot(int(d["index"]))
    o = shot.entry.outcome
    if o is not None:
        shot.inbound = shot.inbound if o.inbound_speed_m_s is None else o.inbound_speed_m_s
        shot.rebound = shot.rebound if o.rebound_speed_m_s is None else o.rebound_speed_m_s
    if shot.entry.valid:
        r.note(f"shot {shot.index} valid: {r.metric_name} {shot.metric:.4f} +- {shot.u:.4f}")
    else:
        codes = ", ".join(x.split(":")[0] for x in shot.reasons) or "invalid"
        r.note(f"shot {shot.index} invalid ({codes}): re-shoot")


def _lost(r: LiveRun, d: dict[str, Any]) -> None:
    shot = r._shot(int(d["index"]))
    r.note(f"shot {shot.index} lost: {d.get('reason', '')}")


def _overruled(r: LiveRun, d: dict[str, Any]) -> None:
    shot = r._shot(int(d["index"]))
    r.note(f"shot {shot.index} rejected on review: re-shoot")


def _chosen(r: LiveRun, d: dict[str, Any]) -> None:
    best = r.run.best_location_in
    r.best_location_in = float(best if best is not None else d["from_barrel_end_in"])
    r.note(f"location of maximum performance: {r.best_location_in:g} in from the tip")


def _ball(r: LiveRun, d: dict[str, Any]) -> None:
    r.note(f"ball replaced: ball {d['ball_number']}")


def _answered(r: LiveRun, d: dict[str, Any]) -> None:
    if not d["prompt_id"].startswith("fire-"):
        how = f" (given with {d.get('with_prompt')})" if d.get("given") == "with" else ""
        r.note(f"{d['prompt_id']}: {'yes' if d['answer'] else 'NO'}{how}")


def _traffic(r: LiveRun, d: dict[str, Any]) -> None:
    """Decode the device traffic into lines: 'cannon > 1 STATUS*7D7D' (> sent, < received)."""
    for chunk in d.get("chunks", []):
        key = (str(chunk.get("device", "?")), str(chunk.get("dir", "?")))
        try:
            text = base64.b64decode(chunk.get("data_b64", "")).decode("ascii", "replace")
        except ValueError:
            text = "<undecodable>\n"
        *done, rest = (r._partial.pop(key, "") + text).split("\n")
        for line in done:
            if line.strip():
                r.traffic.append(f"{key[0]:<6} {'>' if key[1] == 'tx' else '<'} {line.strip()}")
        if rest:
            r._partial[key] = rest


def _finished(r: LiveRun, d: dict[str, Any]) -> None:
    v = r.verdict = r.run.verdict
    assert v is not None, "the fold took the RunFinished first"
    cc = v.cross_check or {}
    if cc.get("predicted") is not None:
        r.prediction = float(cc["predicted"])
        flagged = cc.get("flagged")
        r.prediction_note = (
            "uncalibrated: not judged"
            if flagged is None
            else ("FLAGGED: out of line" if flagged else "consistent (run's check)")
        )
    r.note(f"verdict: {v.verdict}" + (f" ({v.zone})" if v.zone else ""))


def _interrupted(r: LiveRun, d: dict[str, Any]) -> None:
    r.interrupted = str(d.get("reason", ""))
    r.note(f"interrupted: {r.interrupted}")


def _paused(r: LiveRun, d: dict[str, Any]) -> None:
    r.paused = True
    r.note("paused before the next shot")


def _continued(r: LiveRun, d: dict[str, Any]) -> None:
    r.paused = False
    r.note("continued")


_HANDLERS = {
    ev.RIG_NAMED: _rig_named,
    ev.RUN_STARTED: _started,
    ev.RUN_RESUMED: _resumed,
    ev.ENVIRONMENT_CHECKED: _environment,
    ev.MOI_MEASURED: _moi,
    ev.SHOT_REQUESTED: _requested,
    ev.GATE_CROSSED: _crossed,
    ev.INBOUND_MEASURED: _inbound,
    ev.REBOUND_MEASURED: _rebound,
    ev.SHOT_FIRED: _fired,
    ev.SHOT_MEASURED: _measured,
    ev.SHOT_REJECTED: _measured,
    ev.SHOT_LOST: _lost,
    ev.SHOT_OVERRULED: _overruled,
    ev.LOCATION_CHOSEN: _chosen,
    ev.BALL_REPLACED: _ball,
    ev.OPERATOR_ANSWERED: _answered,
    ev.RUN_FINISHED: _finished,
    ev.TRAFFIC: _traffic,
    ev.RUN_INTERRUPTED: _interrupted,
    ev.RUN_PAUSED: _paused,
    ev.RUN_CONTINUED: _continued,
}
