"""Session events: past-tense facts that flow upwards to the store, the UI and reports.

Every event is a frozen dataclass with its `kind` as a class constant (an evaluated shot's kind
says its validity: ShotMeasured or ShotRejected). Persisted kinds are written to the record store
(in order; a commit point at once with those held before it, the others held until the next one:
RunEvent.commits, rig.store.RunWriter); the others are for live display only and can be
recomputed from persisted ones.

The log's JSON payload of an event is its typed fields; an event that carries a typed record
(ShotEvaluated's ShotOutcome, MoiMeasured's MoiResult, RunFinished's RunVerdict: rig.core.outcomes)
writes the record's fields flat beside its own, as these payloads have been written from the start
(LOG_FORMAT 1). `to_payload` and `from_payload` are the only translation, so a payload read from the
log and written back is the same JSON. `extra` holds the payload keys an event does not type: only
records written by older code have them (the gate speeds an old ShotFired also held); the producers
of this code write none (tests/store/test_events.py checks every event of a run). Dataclasses, not
pydantic models: an event is built on every gate crossing (the 1 ms path from the last gate to the
metric) and the payloads' contents are validated where they are made (procedure, bat and rig
models, the measurement code).

Why one module of ~400 lines: the event vocabulary is kept in one place on purpose (issue 11):
every kind, its fields and its one translation to and from the log, so no kind is spelled twice.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import Any, ClassVar

from rig.core.outcomes import EventFormatError, MoiResult, PayloadRecord, RunVerdict, ShotOutcome, Verdict

LOG_FORMAT = 1  # version of the payloads below in the record store's log

__all__ = ["EventFormatError", "MoiResult", "RunVerdict", "ShotOutcome", "Verdict"]


@dataclass(frozen=True)
class RunEvent:
    """One fact about a run: the base of every event class.

    RECORD names the field holding a typed record written flat into the payload (None: none);
    WRITTEN the optional fields written even when None (the producers always wrote them).
    """

    kind: ClassVar[str] = ""
    persisted: ClassVar[bool] = True
    RECORD: ClassVar[str | None] = None
    WRITTEN: ClassVar[frozenset[str]] = frozenset()
    WAITS: ClassVar[bool] = False  # may wait for the next commit point: see `commits`
    extra: Mapping[str, Any] = field(default_factory=dict, kw_only=True)

    @property
    def commits(self) -> bool:
        """A commit point: written at once, with the entries held before it, in one transaction.
        An event that waits (WAITS) is one a resumed run makes again (a start, a prompt, a location,
        a scripted answer), or part of the shot in flight (its raw record and traffic, written with
        its outcome); a crash loses only such entries (rig.store.RunWriter, docs/records.md)."""
        return not self.WAITS

    @cached_property
    def data(self) -> dict[str, Any]:
        """The log payload (JSON-ready); see to_payload."""
        return to_payload(self)


@dataclass(frozen=True)
class LiveEvent(RunEvent):
    """An event for live display only: never written to the store."""

    persisted: ClassVar[bool] = False


# -- persisted ---------------------------------------------------------------------------------
ONE_SHOT_KIND = "shot"  # a one-shot run's procedure name in the store (rig shot), shown where a
# certification shows its procedure
CHECK_KIND = "check"  # a check run's (rig check): the reference bat again, never a bat of a population
CHECK_ACKNOWLEDGED = "CheckAcknowledged"  # lab-level: a rig's chart signals acknowledged (rig check ack)
CHECK_RESTARTED = "CheckRestarted"  # lab-level: a new phase I for a rig and reference bat (rig check restart)
BY_SCRIPT = "script"  # OperatorAnswered.given when a script answered (rig.protocols.control.SCRIPT)


@dataclass(frozen=True)
class RunStarted(RunEvent):
    """The run's procedure, bat and rig as run (extra: software, calibration)."""

    kind: ClassVar[str] = "RunStarted"
    WAITS: ClassVar[bool] = True
    procedure: dict[str, Any]
    bat: dict[str, Any]
    rig: dict[str, Any]
    software: dict[str, Any] | None = None  # rig.core.version.software()
    calibration: dict[str, Any] | None = None  # the model calibration, whole (protocols.verdict)
    ball: dict[str, Any] | None = None  # the ball terms of a run with a ball lot
    lot: dict[str, Any] | None = None  # a ball test's lot
    test: str | None = None  # a ball test's kind
    one_shot: bool | None = None  # a one-shot run (rig shot)
    plan: str | None = None  # a lab's own plan (module.function); None for the standard one


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
    WAITS: ClassVar[bool] = True
    shots_so_far: int


@dataclass(frozen=True)
class EnvironmentChecked(RunEvent):
    kind: ClassVar[str] = "EnvironmentChecked"
    WAITS: ClassVar[bool] = True
    temperature_c: float
    humidity_pct: float
    ok: bool


@dataclass(frozen=True)
class MoiMeasured(RunEvent):
    """The bat's MOI with its uncertainty, entered or timed (rig.core.outcomes.MoiResult)."""

    kind: ClassVar[str] = "MoiMeasured"
    RECORD: ClassVar[str | None] = "result"
    result: MoiResult


@dataclass(frozen=True)
class OperatorPrompted(RunEvent):
    kind: ClassVar[str] = "OperatorPrompted"
    WAITS: ClassVar[bool] = True
    prompt_id: str
    text: str


@dataclass(frozen=True)
class OperatorAnswered(RunEvent):
    """An answer; `given` says how (protocols.control: asked, with another prompt's answer, by a
    script; None in records made before it was kept, or when the operator did not say)."""

    kind: ClassVar[str] = "OperatorAnswered"
    prompt_id: str
    answer: bool
    who: str | None = None
    given: str | None = None
    with_prompt: str | None = None  # the prompt whose answer gave this one

    @property
    def commits(self) -> bool:
        """A person's answer is written at once; a script's waits for the next commit point."""
        return self.given != BY_SCRIPT


@dataclass(frozen=True)
class LocationSet(RunEvent):
    kind: ClassVar[str] = "LocationSet"
    WAITS: ClassVar[bool] = True
    from_barrel_end_in: float
    impact_from_pivot_m: float | None = None


@dataclass(frozen=True)
class ShotRequested(RunEvent):
    """Intent, committed before FIRE: a resume never fires it twice."""

    kind: ClassVar[str] = "ShotRequested"
    index: int
    purpose: str  # "scan", "valid", or a ball test's "ball"; a one-shot run's "shot"
    location_in: float
    target_speed_m_s: float | None = None
    aim_speed_m_s: float | None = None  # what the cannon was asked, after the learned aim
    impact_from_pivot_m: float | None = None
    temperature_c: float | None = None  # the lab's air at the shot, where the run read it
    humidity_pct: float | None = None
    ball: str | None = None  # a ball test's ball, its slot and planned hit
    ball_hit: int | None = None
    planned_hit: int | None = None
    slot: int | None = None


@dataclass(frozen=True)
class ShotFired(RunEvent):
    """The raw record of a fired shot, committed with (never after) what is derived from it: the gate
    events, the gates' configuration and positions, the recoil, the device data and the ball. The
    speeds derived from it are the evaluation's (ShotEvaluated); older records held them here too
    (in `extra`). A shot nothing came back from has no crossings."""

    kind: ClassVar[str] = "ShotFired"
    WAITS: ClassVar[bool] = True
    WRITTEN: ClassVar[frozenset[str]] = frozenset({"recoil_rad_s"})
    index: int
    crossings: list[Any] | None = None
    ball_number: int | None = None
    ball: str | None = None
    ball_hits: int | None = None  # the ball's hits before this shot
    shot_number: int | None = None
    target_speed_m_s: float | None = None
    pressure_kpa: float | None = None
    impact_from_pivot_m: float | None = None
    gate_positions_m: list[float] | None = None
    gate_config: dict[str, Any] | None = None
    recoil_rad_s: float | None = None
    notes: list[str] | None = None


@dataclass(frozen=True)
class ShotEvaluated(RunEvent):
    """A fired shot's evaluation (rig.core.outcomes.ShotOutcome): its kind says its validity,
    ShotMeasured for a valid shot and ShotRejected for an invalid one, as the log has named them."""

    kind: ClassVar[str] = "ShotMeasured"
    KINDS: ClassVar[tuple[str, str]] = ("ShotMeasured", "ShotRejected")
    RECORD: ClassVar[str | None] = "outcome"
    index: int
    outcome: ShotOutcome

    def __post_init__(self) -> None:
        self.__dict__["kind"] = self.KINDS[0] if self.outcome.valid else self.KINDS[1]

    @property
    def valid(self) -> bool:
        """Whether the shot is valid."""
        return self.outcome.valid


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
    WAITS: ClassVar[bool] = True
    ball_number: int
    ball: str | None = None  # a ball test's ball id


@dataclass(frozen=True)
class LocationChosen(RunEvent):
    kind: ClassVar[str] = "LocationChosen"
    WAITS: ClassVar[bool] = True
    from_barrel_end_in: float
    mean_metric: float | None = None
    scan: dict[str, float] | None = None
    bracketed: bool | None = None  # whether the scan bracketed the maximum
    accepted_by: str | None = None  # who accepted a location the scan did not bracket


@dataclass(frozen=True)
class RunFinished(RunEvent):
    """The verdict and what decided it (rig.core.outcomes.RunVerdict)."""

    kind: ClassVar[str] = "RunFinished"
    RECORD: ClassVar[str | None] = "result"
    result: RunVerdict


@dataclass(frozen=True)
class RunInterrupted(RunEvent):
    kind: ClassVar[str] = "RunInterrupted"
    reason: str | None = None
    budget_exceeded: bool | None = None  # stopped by the re-shoot budget
    where: str | None = None  # the step a plan error stopped in


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
    WAITS: ClassVar[bool] = True
    from_barrel_end_in: float
    impact_from_pivot_m: float | None = None
    reason: str | None = None


@dataclass(frozen=True)
class CompressionMeasured(RunEvent):
    """A barrel-compression reading of the accelerated break-in (stage 0: the new bat)."""

    kind: ClassVar[str] = "CompressionMeasured"
    stage: int
    force_lbf: float
    displacement_in: float
    location_in: float


@dataclass(frozen=True)
class BarrelRolled(RunEvent):
    """A rolling step of the accelerated break-in, as the operator reported it (`given`: as an
    OperatorAnswered's); `hoop_hz` (with its standard u) if the operator measured it after rolling."""

    kind: ClassVar[str] = "BarrelRolled"
    stage: int
    depth_in: float
    passes: int
    who: str | None = None
    given: str | None = None
    hoop_hz: float | None = None
    hoop_u_hz: float | None = None


@dataclass(frozen=True)
class AbiStageMeasured(RunEvent):
    """One stage's BBCOR of the accelerated break-in: a RunVerdict's payload (mean, U, cross-check
    from the stage's hoop frequency), and that hoop frequency where measured."""

    kind: ClassVar[str] = "AbiStageMeasured"
    stage: int
    result: dict[str, Any]
    hoop_hz: float | None = None


@dataclass(frozen=True)
class Traffic(RunEvent):
    """Device traffic, base64 chunks, attached to a shot (index) or to none."""

    kind: ClassVar[str] = "Traffic"
    WAITS: ClassVar[bool] = True
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
    ShotEvaluated,
    ShotLost,
    ShotOverruled,
    BallReplaced,
    LocationChosen,
    RunFinished,
    RunInterrupted,
    RigChecked,
    RunEnded,
    ScanExtended,
    CompressionMeasured,
    BarrelRolled,
    AbiStageMeasured,
    Traffic,
    GateCrossed,
    InboundMeasured,
    ReboundMeasured,
    DeviceStatus,
    RigNamed,
    RunPaused,
    RunContinued,
)
BY_KIND: dict[str, type[RunEvent]] = {t.kind: t for t in EVENT_TYPES} | dict.fromkeys(
    ShotEvaluated.KINDS, ShotEvaluated
)
_FIELDS: dict[type[RunEvent], tuple[str, ...]] = {
    t: tuple(f.name for f in fields(t) if f.name not in ("extra", t.RECORD)) for t in EVENT_TYPES
}
# typed fields a payload may lack (old runs, or a producer with nothing to say): None when absent
_OPTIONAL: dict[type[RunEvent], frozenset[str]] = {
    t: frozenset(f.name for f in fields(t) if f.name != "extra" and f.default is None) for t in EVENT_TYPES
}
RECORDS: dict[type[RunEvent], type[PayloadRecord]] = {
    ShotEvaluated: ShotOutcome,
    MoiMeasured: MoiResult,
    RunFinished: RunVerdict,
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
SHOT_MEASURED, SHOT_REJECTED = ShotEvaluated.KINDS
SHOT_LOST = ShotLost.kind
SHOT_OVERRULED = ShotOverruled.kind
BALL_REPLACED = BallReplaced.kind
LOCATION_CHOSEN = LocationChosen.kind
RUN_FINISHED = RunFinished.kind
RUN_INTERRUPTED = RunInterrupted.kind
RIG_CHECKED = RigChecked.kind
RUN_ENDED = RunEnded.kind
SCAN_EXTENDED = ScanExtended.kind
COMPRESSION_MEASURED = CompressionMeasured.kind
BARREL_ROLLED = BarrelRolled.kind
ABI_STAGE_MEASURED = AbiStageMeasured.kind
ABI_KINDS = (COMPRESSION_MEASURED, BARREL_ROLLED, ABI_STAGE_MEASURED)
ABI_DAMAGE_PROMPT = "abi-intact-"  # an ABI stage's inspection prompt: its id, then the stage
ABI_PLAN = "rig.protocols.abi.abi"  # the accelerated break-in plan's recorded name (RunStarted.plan)
TRAFFIC = Traffic.kind
GATE_CROSSED = GateCrossed.kind
INBOUND_MEASURED = InboundMeasured.kind
REBOUND_MEASURED = ReboundMeasured.kind
DEVICE_STATUS = DeviceStatus.kind
RIG_NAMED = RigNamed.kind
RUN_PAUSED = RunPaused.kind
RUN_CONTINUED = RunContinued.kind

PERSISTED = frozenset(k for k, t in BY_KIND.items() if t.persisted)
SHOT_KINDS = (SHOT_REQUESTED, SHOT_FIRED, SHOT_MEASURED, SHOT_REJECTED, SHOT_LOST, SHOT_OVERRULED)
STOP_KINDS = (RUN_INTERRUPTED, RUN_RESUMED, RIG_CHECKED, RUN_ENDED)  # breaks in a run's course


def to_payload(event: RunEvent) -> dict[str, Any]:
    """The event's log payload: its typed fields (optional ones only when set), its record's
    fields flat, then the untyped rest.

    An event read from the log keeps the payload as read (`data`); this builds it for one made in code.
    """
    cls = type(event)
    optional = _OPTIONAL[cls]
    read: frozenset[str] | None = event.__dict__.get("_read")  # the keys of a payload as read
    written = cls.WRITTEN if read is None else read
    payload = {
        name: value
        for name in _FIELDS[cls]
        if (value := getattr(event, name)) is not None or name not in optional or name in written
    }
    if cls.RECORD is not None:
        payload.update(getattr(event, cls.RECORD).to_payload())
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
    rest = {k: v for k, v in payload.items() if k not in names}
    own: dict[str, Any] = {n: payload[n] for n in names if n in payload}
    try:
        if cls.RECORD is None:
            typed = cls(**own, extra=rest)
        else:
            fields_in = _validity(kind, rest) if cls is ShotEvaluated else rest
            record: Any = RECORDS[cls].from_payload(fields_in, kind, read=tuple(rest))
            typed = cls(**own, **{cls.RECORD: record})
    except ValueError as exc:
        raise EventFormatError(f"{kind} payload: {exc}") from None
    typed.__dict__["data"] = payload if isinstance(payload, dict) else dict(payload)  # as read, key order too
    typed.__dict__["_read"] = frozenset(payload)
    return typed


def _validity(kind: str, rest: dict[str, Any]) -> dict[str, Any]:
    """An evaluated shot's record with its validity: the kind's, which a payload's own must match."""
    valid = kind == SHOT_MEASURED
    if rest.get("valid", valid) is not valid:
        raise EventFormatError(f"{kind} payload says valid {rest['valid']!r}")
    return {**rest, "valid": valid} if "valid" not in rest else rest


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
