"""The typed records a run's evaluation produces: a shot's outcome, the MOI result and the verdict.

Events carry them (rig.core.events: ShotEvaluated, MoiMeasured, RunFinished) and the fold keeps them
(rig.core.run_state), so every reader names a field, never a string key. Each record's log payload is
its fields, flat, as the payload dicts these records replace were written: `to_payload` and
`from_payload` are the one translation, and a payload read and written back is the same JSON.
Fields a record does not name (a record written by other code) are kept in `rest`, as read.

Open-ended documents inside a record (a budget, the cross-check, the drag summary, a shot's inputs)
stay JSON mappings: their shape belongs to the code that makes them (rig.measure, rig.population).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from enum import StrEnum
from types import MappingProxyType
from typing import Any, ClassVar, Self

from rig.core.errors import RigError


class Verdict(StrEnum):
    """A certification's verdict; str-valued, so payloads hold "PASS" and "FAIL" as before."""

    PASS = "PASS"
    FAIL = "FAIL"


SHOWN = MappingProxyType({"shown": True})
"""A record field's metadata: the report shows the field where it is set (ShotOutcome.shown)."""


class EventFormatError(RigError, ValueError):
    """A log payload that is not the event its kind says (a damaged record: one line, no traceback)."""


@dataclass(frozen=True)
class PayloadRecord:
    """A typed record written flat into an event's payload (the base of the records below).

    A record read from a payload writes back the keys the payload had, in its order (`read`), so
    the JSON is the same; one made in code writes its required fields, the optional ones that are
    set, and those `WRITTEN` names even when None (the producers always wrote them, as null).
    """

    WRITTEN: ClassVar[frozenset[str]] = frozenset()
    rest: Mapping[str, Any] = field(default_factory=dict, kw_only=True)
    read: tuple[str, ...] = field(default=(), kw_only=True, compare=False, repr=False)
    """The keys of the payload as read, in its order (empty: a record made in code)."""

    def to_payload(self) -> dict[str, Any]:
        """The record's payload keys: its fields (optional ones only when set), then `rest`."""
        required, optional = _names(type(self))
        if self.read:
            values = {n: getattr(self, n) for n in (*required, *optional)} | dict(self.rest)
            out = {k: values[k] for k in self.read if k in values}
            defaults = _defaults(type(self))  # a field the payload lacked is written once it differs
            out.update({n: v for n in optional if n not in out and (v := values[n]) != defaults[n]})
            return out
        out = {n: getattr(self, n) for n in required}
        out.update({n: v for n in optional if (v := getattr(self, n)) is not None or n in self.WRITTEN})
        out.update(self.rest)
        return out

    @classmethod
    def from_payload(
        cls, payload: Mapping[str, Any], what: str = "", read: tuple[str, ...] | None = None
    ) -> Self:
        """The record in a payload; EventFormatError if a required field is missing. `read`: the
        payload's keys as written back (default: the payload's own)."""
        required, optional = _names(cls)
        missing = [n for n in required if n not in payload]
        if missing:
            raise EventFormatError(f"{what or cls.__name__} payload lacks {', '.join(missing)}")
        known = {*required, *optional}
        return cls(
            **{n: payload[n] for n in known if n in payload},
            rest={k: v for k, v in payload.items() if k not in known},
            read=tuple(payload) if read is None else read,
        )


_NAMES: dict[type, tuple[tuple[str, ...], tuple[str, ...]]] = {}
_DEFAULTS: dict[type, dict[str, Any]] = {}
_SHOWN: dict[type, tuple[str, ...]] = {}


def _names(cls: type) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(required, optional) field names of a record, in declaration order."""
    if cls not in _NAMES:
        own = [f for f in fields(cls) if f.name not in ("rest", "read")]
        required = tuple(f.name for f in own if f.default is MISSING and f.default_factory is MISSING)
        _NAMES[cls] = required, tuple(f.name for f in own if f.name not in required)
    return _NAMES[cls]


def _defaults(cls: type) -> dict[str, Any]:
    """Each optional field's default value (a factory's value for a list)."""
    if cls not in _DEFAULTS:
        _DEFAULTS[cls] = {
            f.name: f.default if f.default_factory is MISSING else f.default_factory()
            for f in fields(cls)
            if f.name in _names(cls)[1]
        }
    return _DEFAULTS[cls]


@dataclass(frozen=True)
class ShotOutcome(PayloadRecord):
    """A fired shot's evaluation: its speeds, metrics, u, validity and the reasons.

    A certification shot has its metrics, budget and inputs (the budget's input distributions, as
    rig.measure.model.ShotInputs writes them); a ball-test shot its ball and systematic u; a one-shot
    run's shot only its speeds and e_A. The speeds derived from the gates are recorded here only:
    the raw record (ShotFired) keeps the gate events they come from.
    """

    WRITTEN: ClassVar[frozenset[str]] = frozenset({"metric", "u"})
    valid: bool
    metric_name: str | None = None  # the procedure's standard (a one-shot run's "e_a")
    reasons: list[Any] = field(default_factory=list)
    metric: float | None = None
    u: float | None = None
    inbound_speed_m_s: float | None = None
    rebound_speed_m_s: float | None = None
    inbound_at_impact_m_s: float | None = None  # drag-corrected to the impact point (none in old runs)
    rebound_at_impact_m_s: float | None = None
    pair_speeds_m_s: dict[str, float | None] | None = None  # each gate pair's speed (one-shot runs)
    aim_factor: float | None = None  # the aim after this shot (certification shots)
    aim_shots: int | None = None  # shots that taught it
    metrics: dict[str, float] | None = None
    budget: dict[str, Any] | None = None
    inputs: dict[str, Any] | None = None
    target_speed_m_s: float | None = None
    impact_from_pivot_m: float | None = None
    ball: str | None = None  # a ball test's ball and its hit
    ball_hit: int | None = None
    u_systematic: float | None = None
    dry_run: bool | None = None  # a rehearsal's nominal shot: nothing was fired

    def __post_init__(self) -> None:
        object.__setattr__(self, "valid", bool(self.valid))

    def shown(self) -> dict[str, Any]:
        """The set fields declared `SHOWN`: the report shows them with each shot, as declared."""
        cls = type(self)
        if cls not in _SHOWN:
            _SHOWN[cls] = tuple(f.name for f in fields(cls) if f.metadata.get("shown"))
        return {n: v for n in _SHOWN[cls] if (v := getattr(self, n)) is not None}


@dataclass(frozen=True)
class MoiResult(PayloadRecord):
    """The bat's MOI and its standard uncertainty, entered or timed on the pendulum, with the budget's
    contributions and (timed) the pendulum's periods."""

    moi_kgm2: float
    u_kgm2: float | None = None
    relative_u: float | None = None
    source: str | None = None
    contributions: list[Any] | None = None
    period_s: float | None = None
    periods_s: list[float] | None = None
    periods_host_u_s: list[float] | None = None  # the host clock's u of each period, where known
    cycles: int | None = None
    amplitude_deg: float | None = None

    @property
    def timed(self) -> bool:
        """Whether the MOI was timed on the pendulum (else entered from the bat file)."""
        return self.periods_s is not None


@dataclass(frozen=True)
class RunVerdict(PayloadRecord):
    """A run's verdict: PASS or FAIL against the limit, with what decided it.

    A certification's has the mean of the valid hits, its u and U, the decision rule, the budget,
    the ball terms, the drag correction, the cross-check and the time/accuracy trade-off; a failed
    ring check only its `reason`; a ball test's the lot's result against its specification.
    """

    WRITTEN: ClassVar[frozenset[str]] = frozenset({"metric", "limit"})
    verdict: Verdict
    metric: str | None = None
    limit: float | None = None
    zone: str | None = None
    definition: str | None = None
    mean: float | None = None
    u: float | None = None
    U: float | None = None
    coverage_k: float | None = None
    decision_rule: str | None = None
    n_hits: int | None = None
    hits: list[float] | None = None
    location_in: float | None = None
    impact_from_pivot_m: float | None = None
    moi_kgm2: float | None = None
    edition: str | None = None
    budget: dict[str, Any] | None = None
    ball: dict[str, Any] | None = None
    bpf: dict[str, Any] | None = None  # a BPF's parts: mean BBCOR, the ball COR (lot, u), u(BPF)
    drag: dict[str, Any] | None = None
    cross_check: dict[str, Any] | None = None
    tradeoff: list[Any] | None = None
    reason: str | None = None  # a verdict decided before any shot (a failed ring check)
    lot: str | None = None  # a ball test: the lot, its result against the specification
    lot_result: dict[str, Any] | None = None
    meets_specification: bool | None = None
    nominal: float | None = None
    tolerance: float | None = None
    dry_run: bool | None = None  # a rehearsal decides nothing

    def __post_init__(self) -> None:
        object.__setattr__(self, "verdict", Verdict(self.verdict))

    @property
    def passed(self) -> bool:
        """Whether the verdict is PASS."""
        return self.verdict is Verdict.PASS
