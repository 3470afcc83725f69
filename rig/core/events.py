"""Session events: past-tense facts that flow upwards to the store, the UI and reports.

Every event is a frozen dataclass with its `kind` as a class constant. Persisted kinds are
written to the record store (in order, each committed before the run goes on); the others are
for live display only and can be recomputed from persisted ones.

The log's JSON payload of an event is its typed fields plus `extra`, the payload keys the class
does not type (open-ended documents such as a verdict's budget, or keys only some runs write).
`to_payload` and `from_payload` are the only translation between the two, so a payload read
from the log and written back is the same JSON: LOG_FORMAT 1 is the format these payloads have
had from the start. Dataclasses, not pydantic models: an event is built on every gate crossing
(the 1 ms path from the last gate to the metric) and the payloads' contents are validated where
they are made (procedure, bat and rig models, the measurement code).

Why one module of ~400 lines: the event vocabulary is kept in one place on purpose (issue 11):
every kind, its fields and its one translation to and from the log, so no kind is spelled twice.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from enum import StrEnum
from functools import cached_property
from typing import Any, ClassVar

from rig.core.errors import RigError

LOG_FORMAT = 1  # version of the payloads below in the record store's log


class Verdict(StrEnum):
    """A certification's verdict; str-valued, so payloads hold "PASS" and "FAIL" as before."""

    PASS = "PASS"
    FAIL = "FAIL"


class EventFormatError(RigError, ValueError):
    """A log payload that is not the event its kind says (a damaged record: one line, no traceback)."""


@dataclass(frozen=True)
class RunEvent:
    """One fact about a run: the base of every event class."""

    kind: ClassVar[str] = ""
    persisted: ClassVar[bool] = True
    extra: Mapping[str, Any] = field(default_factory=dict, kw_only=True)

    @cached_property
    def data(self) -> dict[str, Any]:
        """The log payload (JSON-ready); see to_payload."""
        return to_payload(self)


@dataclass(frozen=True)
class LiveEvent(RunEvent):
    """An event for live display only: never written to the store."""

    persisted: ClassVar[bool] = False


# -- persisted ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunStarted(RunEvent):
    """The run's procedure, bat and rig as run (extra: software, calibration)."""

    kind: ClassVar[str] = "RunStarted"
    procedure: dict[str, Any]
    bat: dict[str, Any]
    rig: dict[str, Any]


@dataclass(frozen=True)
class InstrumentsIdentified(RunEvent):
    """What each device said it is when the session opened, with its equipment-list entry and
    calibration status (rig.instruments); `override`: who accepted an overdue calibration, and why."""

    kind: ClassVar[str] = "InstrumentsIdentified"
    devices: dict[str, Any]
    equipment: list[Any]
    override: dict[str, Any] | None = None


@dataclass(frozen=True)
class RunResumed(RunEvent):
    kind: ClassVar[str] = "RunResumed"
    shots_so_far: int


@dataclass(frozen=True)
class EnvironmentChecked(RunEvent):
    kind: ClassVar[str] = "EnvironmentChecked"
    temperature_c: float
    humidity_pct: float
    ok: bool


@dataclass(frozen=True)
class MoiMeasured(RunEvent):
    """The bat's MOI and its standard uncertainty (extra: contributions, pendulum timings)."""

    kind: ClassVar[str] = "MoiMeasured"
    moi_kgm2: float
    u_kgm2: float | None = None


@dataclass(frozen=True)
class OperatorPrompted(RunEvent):
    kind: ClassVar[str] = "OperatorPrompted"
    prompt_id: str
    text: str


@dataclass(frozen=True)
class OperatorAnswered(RunEvent):
    kind: ClassVar[str] = "OperatorAnswered"
    prompt_id: str
    answer: bool
    who: str | None = None


@dataclass(frozen=True)
class LocationSet(RunEvent):
    kind: ClassVar[str] = "LocationSet"
    from_barrel_end_in: float
    impact_from_pivot_m: float | None = None


@dataclass(frozen=True)
class ShotRequested(RunEvent):
    """Intent, committed before FIRE: a resume never fires it twice."""

    kind: ClassVar[str] = "ShotRequested"
    index: int
    purpose: str  # "scan" or "valid"
    location_in: float


@dataclass(frozen=True)
class ShotFired(RunEvent):
    """Raw gate ticks, recoil, device data: committed before derivation (extra: the raw record)."""

    kind: ClassVar[str] = "ShotFired"
    index: int
    crossings: list[Any] | None = None


@dataclass(frozen=True)
class ShotMeasured(RunEvent):
    """A valid shot's measurement (extra: speeds, metric, u, budget, reasons)."""

    kind: ClassVar[str] = "ShotMeasured"
    index: int
    metric: float | None = None
    valid: bool | None = None


@dataclass(frozen=True)
class ShotRejected(RunEvent):
    """An invalid shot's measurement and the reasons (extra as ShotMeasured)."""

    kind: ClassVar[str] = "ShotRejected"
    index: int
    metric: float | None = None
    valid: bool | None = None


@dataclass(frozen=True)
class ShotLost(RunEvent):
    kind: ClassVar[str] = "ShotLost"
    index: int
    reason: str | None = None


@dataclass(frozen=True)
class ShotOverruled(RunEvent):
    """The operator rejected a valid shot on review."""

    kind: ClassVar[str] = "ShotOverruled"
    index: int
    reason: str | None = None
    who: str | None = None


@dataclass(frozen=True)
class BallReplaced(RunEvent):
    kind: ClassVar[str] = "BallReplaced"
    ball_number: int


@dataclass(frozen=True)
class LocationChosen(RunEvent):
    kind: ClassVar[str] = "LocationChosen"
    from_barrel_end_in: float
    mean_metric: float | None = None
    scan: dict[str, float] | None = None


@dataclass(frozen=True)
class RunFinished(RunEvent):
    """The verdict (extra: mean, U, hits, budget, cross-check, or a failed ring check's reason)."""

    kind: ClassVar[str] = "RunFinished"
    verdict: Verdict
    metric: str | None = None
    limit: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "verdict", Verdict(self.verdict))


@dataclass(frozen=True)
class RunInterrupted(RunEvent):
    kind: ClassVar[str] = "RunInterrupted"
    reason: str | None = None


@dataclass(frozen=True)
class RigChecked(RunEvent):
    """The operator confirms the rig was checked: the re-shoot budget starts again."""

    kind: ClassVar[str] = "RigChecked"
    who: str | None = None
    why: str | None = None
    invalid_shots_before: int | None = None


@dataclass(frozen=True)
class RunEnded(RunEvent):
    """The run ended on the operator's word, with no verdict."""

    kind: ClassVar[str] = "RunEnded"
    who: str | None = None
    why: str | None = None
    shots_so_far: int | None = None


@dataclass(frozen=True)
class ScanExtended(RunEvent):
    """A location added beyond the scan to bracket the maximum."""

    kind: ClassVar[str] = "ScanExtended"
    from_barrel_end_in: float
    impact_from_pivot_m: float | None = None
    reason: str | None = None


@dataclass(frozen=True)
class Traffic(RunEvent):
    """Device traffic, base64 chunks, attached to a shot (index) or to none."""

    kind: ClassVar[str] = "Traffic"
    index: int | None
    chunks: list[dict[str, Any]]


# -- live only ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class GateCrossed(LiveEvent):
    kind: ClassVar[str] = "GateCrossed"
    index: int
    gate: int
    tick: int
    host_time_s: float


@dataclass(frozen=True)
class InboundMeasured(LiveEvent):
    kind: ClassVar[str] = "InboundMeasured"
    index: int
    speed_m_s: float


@dataclass(frozen=True)
class ReboundMeasured(LiveEvent):
    kind: ClassVar[str] = "ReboundMeasured"
    index: int
    speed_m_s: float


@dataclass(frozen=True)
class DeviceStatus(LiveEvent):
    kind: ClassVar[str] = "DeviceStatus"


@dataclass(frozen=True)
class RigNamed(LiveEvent):
    """The rig the run is recorded on, whether it is simulated, and what its signature will be."""

    kind: ClassVar[str] = "RigNamed"
    name: str
    simulated: bool
    signing: str  # e.g. "signed with rig R's key F", "not signed: ...", or a warning


@dataclass(frozen=True)
class RunPaused(LiveEvent):
    kind: ClassVar[str] = "RunPaused"


@dataclass(frozen=True)
class RunContinued(LiveEvent):
    kind: ClassVar[str] = "RunContinued"


EVENT_TYPES: tuple[type[RunEvent], ...] = (
    RunStarted,
    InstrumentsIdentified,
    RunResumed,
    EnvironmentChecked,
    MoiMeasured,
    OperatorPrompted,
    OperatorAnswered,
    LocationSet,
    ShotRequested,
    ShotFired,
    ShotMeasured,
    ShotRejected,
    ShotLost,
    ShotOverruled,
    BallReplaced,
    LocationChosen,
    RunFinished,
    RunInterrupted,
    RigChecked,
    RunEnded,
    ScanExtended,
    Traffic,
    GateCrossed,
    InboundMeasured,
    ReboundMeasured,
    DeviceStatus,
    RigNamed,
    RunPaused,
    RunContinued,
)
BY_KIND: dict[str, type[RunEvent]] = {t.kind: t for t in EVENT_TYPES}
_FIELDS: dict[type[RunEvent], tuple[str, ...]] = {
    t: tuple(f.name for f in fields(t) if f.name != "extra") for t in EVENT_TYPES
}
# typed fields a payload may lack (old runs, or a producer with nothing to say): None when absent
_OPTIONAL: dict[type[RunEvent], frozenset[str]] = {
    t: frozenset(f.name for f in fields(t) if f.name != "extra" and f.default is None) for t in EVENT_TYPES
}

# The kinds by name (the store and its queries speak kinds)
RUN_STARTED = RunStarted.kind
RUN_RESUMED = RunResumed.kind
INSTRUMENTS_IDENTIFIED = InstrumentsIdentified.kind
ENVIRONMENT_CHECKED = EnvironmentChecked.kind
MOI_MEASURED = MoiMeasured.kind
OPERATOR_PROMPTED = OperatorPrompted.kind
OPERATOR_ANSWERED = OperatorAnswered.kind
LOCATION_SET = LocationSet.kind
SHOT_REQUESTED = ShotRequested.kind
SHOT_FIRED = ShotFired.kind
SHOT_MEASURED = ShotMeasured.kind
SHOT_REJECTED = ShotRejected.kind
SHOT_LOST = ShotLost.kind
SHOT_OVERRULED = ShotOverruled.kind
BALL_REPLACED = BallReplaced.kind
LOCATION_CHOSEN = LocationChosen.kind
RUN_FINISHED = RunFinished.kind
RUN_INTERRUPTED = RunInterrupted.kind
RIG_CHECKED = RigChecked.kind
RUN_ENDED = RunEnded.kind
SCAN_EXTENDED = ScanExtended.kind
TRAFFIC = Traffic.kind
GATE_CROSSED = GateCrossed.kind
INBOUND_MEASURED = InboundMeasured.kind
REBOUND_MEASURED = ReboundMeasured.kind
DEVICE_STATUS = DeviceStatus.kind
RIG_NAMED = RigNamed.kind
RUN_PAUSED = RunPaused.kind
RUN_CONTINUED = RunContinued.kind

PERSISTED = frozenset(t.kind for t in EVENT_TYPES if t.persisted)
SHOT_KINDS = (SHOT_REQUESTED, SHOT_FIRED, SHOT_MEASURED, SHOT_REJECTED, SHOT_LOST, SHOT_OVERRULED)
STOP_KINDS = (RUN_INTERRUPTED, RUN_RESUMED, RIG_CHECKED, RUN_ENDED)  # breaks in a run's course


def to_payload(event: RunEvent) -> dict[str, Any]:
    """The event's log payload: its typed fields (optional ones only when set), then the untyped rest.

    An event read from the log keeps the payload as read (`data`); this builds it for one made in code.
    """
    optional = _OPTIONAL[type(event)]
    payload = {
        name: value
        for name in _FIELDS[type(event)]
        if (value := getattr(event, name)) is not None or name not in optional
    }
    payload.update(event.extra)
    return payload


def from_payload(kind: str, payload: Mapping[str, Any]) -> RunEvent:
    """The typed event of a log entry (format LOG_FORMAT); EventFormatError if it is not one."""
    cls = BY_KIND.get(kind)
    if cls is None:
        raise EventFormatError(f"no event kind {kind!r}")
    names = _FIELDS[cls]
    missing = [n for n in names if n not in payload and n not in _OPTIONAL[cls]]
    if missing:
        raise EventFormatError(f"{kind} payload lacks {', '.join(missing)}")
    extra = {k: v for k, v in payload.items() if k not in names}
    try:
        typed = cls(**{n: payload[n] for n in names if n in payload}, extra=extra)
    except ValueError as exc:
        raise EventFormatError(f"{kind} payload: {exc}") from None
    typed.__dict__["data"] = payload if isinstance(payload, dict) else dict(payload)  # as read, key order too
    return typed


def event(kind: str, **data: Any) -> RunEvent:
    """Compatibility path for producers that still speak a kind and keywords."""
    return from_payload(kind, data)


def parse_log(entries: Iterable[Any]) -> list[RunEvent]:
    """The run events among log entries (kind, payload); store-level records are left out."""
    return [parse_entry(e) for e in entries if e.kind in BY_KIND]


def parse_entry(entry: Any) -> RunEvent:
    """The typed event of one log entry; EventFormatError names the entry if it is not one."""
    try:
        return from_payload(entry.kind, entry.payload)
    except EventFormatError as exc:
        raise EventFormatError(f"log entry {getattr(entry, 'seq', '?')}: {exc}") from None


Subscriber = Callable[[RunEvent], None]
