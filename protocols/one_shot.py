"""A one-shot run's plan (rig.protocols.plan): the one shot `rig shot` asks for, recorded as a run.

Not a certification: no procedure, no bat, no verdict. The clamp holds what it holds and the shot
goes where the stage is put, `OneShot.impact_from_pivot_m` (so the shot's "location" is 0, the
point asked, as a ball test's is the target's face). The plan records the start, puts the stage
there, records the intent (ShotRequested) before FIRE; the executor records the raw record
(ShotFired) or the loss; the plan records the evaluation (the speeds, e_A = rebound / inbound),
then ends the run (RunEnded: a one-shot run has no verdict).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from rig.core import events as ev
from rig.core.outcomes import ShotOutcome
from rig.core.version import software
from rig.protocols.control import RunAborted
from rig.protocols.plan import (
    Checkpoint,
    ClearFault,
    Evaluate,
    Fire,
    Fired,
    Plan,
    PlanContext,
    Prepare,
    Record,
)
from rig.protocols.shot import ShotRecord

KIND = ev.ONE_SHOT_KIND  # the run's kind in the store, shown where a certification shows its procedure
ITEM_ID = "unnamed"  # what the clamp holds: a one-shot run is not told
ITEM_SPEC = {"item": "what the clamp held for a one-shot run (rig shot): not named"}
SHOT_POINT = 0.0  # the one shot goes to the point asked: "location" 0
PURPOSE = "shot"
INDEX = 1


@dataclass(frozen=True)
class OneShot:
    """What a one-shot run is asked: aim for `speed_m_s` with the stage at `impact_from_pivot_m`."""

    speed_m_s: float
    impact_from_pivot_m: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (recorded in the run's start)."""
        return asdict(self)


def evaluation(record: ShotRecord, failure: str = "") -> ShotOutcome:
    """The shot's speeds (each gate pair's too) and e_A (rebound / inbound); invalid, with the reason,
    if not measured."""
    v_in, v_out = record.inbound_speed_m_s, record.rebound_speed_m_s
    return ShotOutcome(
        metric_name="e_a",
        metric=v_out / v_in if v_in and v_out is not None else None,
        valid=not failure,
        reasons=[failure] if failure else [],
        target_speed_m_s=record.target_speed_m_s,
        inbound_speed_m_s=v_in,
        rebound_speed_m_s=v_out,
        pair_speeds_m_s=dict(record.pair_speeds_m_s) or None,
        impact_from_pivot_m=record.impact_from_pivot_m,
    )


@dataclass
class OneShotContext(PlanContext):
    """A plan context for a one-shot run: the shot asked in place of a procedure and a bat."""

    shot: OneShot | None = None

    @property
    def asked(self) -> OneShot:
        """The shot asked."""
        assert self.shot is not None, "a one-shot run needs its shot"
        return self.shot

    def q(self, location_in: float) -> float:
        """The stage position asked (m from the pivot); the one shot goes there."""
        return self.asked.impact_from_pivot_m

    # -- what the executor's backends ask of the context (rig.protocols.executor, rig.protocols.dryrun) --
    def evaluate_shot(self, fired: Fired) -> ShotOutcome:
        """The shot's evaluation."""
        return evaluation(fired.record, fired.failure)

    def rehearsed_shot(self) -> ShotOutcome:
        """A dry run's nominal shot."""
        return ShotOutcome(metric_name="e_a", metric=0.5, valid=True, reasons=[], dry_run=True)


ONE_SHOT_DONE = "one-shot run: the shot was fired and evaluated (no verdict)"


def one_shot(ctx: PlanContext) -> Plan[dict[str, Any]]:
    """Start, put the stage where asked, record the intent, fire once, evaluate; returns the raw
    record and the evaluation. A lost shot stops the run (RunAborted, the loss recorded)."""
    assert isinstance(ctx, OneShotContext), "a one-shot run runs with a OneShotContext"
    asked = ctx.asked
    yield Record(
        ev.RunStarted(
            procedure={"name": "one shot (rig shot)", **asked.as_dict()},
            bat={"id": ITEM_ID, **ITEM_SPEC},
            rig=ctx.config.model_dump(mode="json"),
            software=software(),
            one_shot=True,
        )
    )
    yield ClearFault()
    yield Prepare(SHOT_POINT)
    yield Checkpoint()
    yield Record(
        ev.ShotRequested(
            index=INDEX,
            purpose=PURPOSE,
            location_in=SHOT_POINT,
            target_speed_m_s=asked.speed_m_s,
            aim_speed_m_s=asked.speed_m_s,
            impact_from_pivot_m=ctx.q(SHOT_POINT),
        )
    )
    fired = yield Fire(INDEX, SHOT_POINT, asked.speed_m_s)
    if fired is None:
        raise RunAborted(ctx.state.shots[-1].lost_reason or "the shot was lost")
    outcome: ShotOutcome = yield Evaluate(fired)
    yield Record(ev.ShotEvaluated(index=INDEX, outcome=outcome))
    # a one-shot run has no verdict: it ends as the run table lets a run end without one
    yield Record(ev.RunEnded(who=ctx.who, why=ONE_SHOT_DONE, shots_so_far=1))
    return {"record": fired.record.as_dict(), "evaluation": outcome}
