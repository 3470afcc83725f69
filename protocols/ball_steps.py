"""A ball test's plan (rig.protocols.plan): the lot's balls fired at a rigid target, slot by slot.

The procedure fixes the schedule (rig.protocols.ball_procedure.Slot: speed, ball, the ball's planned
hit); the plan fires the first slot without a valid hit, so the same plan starts a test and resumes
it: every remaining shot goes at its slot's speed with its slot's ball. An invalid or lost shot is
re-shot with the same ball at the same speed (it counts as a hit of that ball if the gates saw it).
Each shot's intent records the ball, the ball's hit count and the lab's air at that shot.

The clamp holds the target the procedure names; the target sits where `target.impact_from_pivot_m`
says, so a shot's "location" is 0 (the target's face) and `BallContext.q` gives the stage position.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rig.core import events as ev
from rig.core.ball import BallLot
from rig.core.errors import ConfigError
from rig.core.outcomes import RunVerdict, ShotOutcome, Verdict
from rig.core.version import software
from rig.protocols import ball_eval, steps
from rig.protocols.ball_procedure import BallProcedure, Slot
from rig.protocols.control import RunAborted
from rig.protocols.plan import (
    Ask,
    Checkpoint,
    ClearFault,
    Decide,
    Evaluate,
    Fire,
    Fired,
    Move,
    Plan,
    PlanContext,
    Prepare,
    Problem,
    ReadEnvironment,
    Record,
)

TARGET_FACE = 0.0  # a ball test's shots all go to the target's face: "location" 0
PURPOSE = "ball"


@dataclass
class BallContext(PlanContext):
    """A plan context for a ball test: the lot, and the target in place of the bat."""

    lot: BallLot | None = None

    @property
    def ball_procedure(self) -> BallProcedure:
        """The test's procedure."""
        assert isinstance(self.procedure, BallProcedure)
        return self.procedure

    def q(self, location_in: float) -> float:
        """The stage position of the target's face from the pivot (m); every shot goes there."""
        return self.ball_procedure.target.impact_from_pivot_m

    def lot_spec(self) -> dict[str, Any]:
        """The lot as recorded (RunStarted), else as given."""
        recorded = (self.state.setup or {}).get("lot")
        if recorded:
            return dict(recorded)
        assert self.lot is not None, "a ball test needs its lot"
        return self.lot.model_dump(mode="json")

    def schedule(self) -> list[Slot]:
        """The test's slots in firing order."""
        return self.ball_procedure.schedule(BallLot.model_validate(self.lot_spec()))

    # -- what the executor's backends ask of the context (rig.protocols.executor, rig.protocols.dryrun) --
    def evaluate_shot(self, fired: Fired) -> ShotOutcome:
        """The shot's measurement."""
        return ball_eval.shot(fired.record, self.ball_procedure, self.state, fired.failure, self.config)

    def decide_run(self) -> RunVerdict:
        """The lot's result."""
        return ball_eval.verdict(self.ball_procedure, self.lot_spec(), self.state)

    def rehearsed_shot(self) -> ShotOutcome:
        """A dry run's nominal valid hit."""
        requested = self.state.shots[-1].requested if self.state.shots else None
        return ShotOutcome(
            metric_name=ball_eval.quantity(self.ball_procedure),
            metric=0.5,
            u=0.0,
            valid=True,
            reasons=[],
            ball=None if requested is None else requested.ball,
            ball_hit=None if requested is None else requested.ball_hit,
            aim_factor=self.state.aim_factor,
            dry_run=True,
        )

    def rehearsed_verdict(self) -> RunVerdict:
        """A dry run decides nothing."""
        return RunVerdict(
            verdict=Verdict.PASS,
            metric=ball_eval.quantity(self.ball_procedure),
            limit=None,
            dry_run=True,
            reason="dry run: nothing was measured",
        )


def preflight(ctx: BallContext) -> Plan[None]:
    """What the rig or the lot cannot do for this test, found before the cannon is armed."""
    p, aim = ctx.ball_procedure, ctx.config.aim
    lo, hi = aim.speed_m_s[0], aim.speed_m_s[-1]
    for speed in p.speeds_m_s:
        for v in (speed - p.speed_tolerance_m_s, speed + p.speed_tolerance_m_s):
            if not lo <= v <= hi:
                yield Problem(f"test speed {v:.2f} m/s is outside the aim calibration ({lo:g}-{hi:g} m/s)")
    lot = BallLot.model_validate(ctx.lot_spec())
    if p.balls_needed > lot.balls:
        yield Problem(f"the test needs {p.balls_needed} balls; lot {lot.id} has {lot.balls}")


def start(ctx: BallContext) -> Plan[None]:
    """Record the test's start (procedure, target, lot, rig, software), or its resumption."""
    if ctx.state.ended is not None:
        raise ConfigError("the run was ended without a result; start a new one", source="resume")
    if not ctx.state.started:
        p = ctx.ball_procedure
        yield Record(
            ev.RunStarted(
                procedure=p.model_dump(mode="json"),
                bat=p.target.spec() | {"id": p.target.id},
                rig=ctx.config.model_dump(mode="json"),
                software=software(),
                test=p.test,
                lot=ctx.lot_spec(),
            )
        )
    else:
        yield Record(ev.RunResumed(shots_so_far=len(ctx.state.shots)))
    yield ClearFault()


def slot_done(ctx: BallContext, slot: Slot) -> bool:
    """True once the slot has its valid hit."""
    return any(
        s.valid and s.requested is not None and s.requested.slot == slot.number for s in ctx.state.shots
    )


def ball_hits(ctx: BallContext, ball_id: str) -> int:
    """The impacts the record gives ball `ball_id` so far (shots of it that the gates saw)."""
    return sum(
        1
        for s in ctx.state.shots
        if s.requested is not None and s.requested.ball == ball_id and s.raw is not None and s.raw.crossings
    )


def loaded_ball(ctx: BallContext) -> str | None:
    """The ball last loaded (recorded with BallReplaced), if any."""
    for noted in reversed(ctx.state.operator):
        if noted.kind == ev.OPERATOR_ANSWERED and str(noted.data.get("prompt_id", "")).startswith("load-"):
            return str(noted.data["prompt_id"]).removeprefix("load-") if noted.data.get("answer") else None
    return None


def load(ctx: BallContext, slot: Slot) -> Plan[None]:
    """Have the slot's ball loaded if another one is (asked and recorded)."""
    if loaded_ball(ctx) == slot.ball_id:
        return
    text = f"Load ball {slot.ball_id} (ball {slot.ball_number} of the test) into the cannon. Done?"
    if not (yield Ask(f"load-{slot.ball_id}", text)):
        raise RunAborted(f"ball {slot.ball_id} not loaded")
    yield Record(ev.BallReplaced(ball_number=slot.ball_number, ball=slot.ball_id))


def shoot(ctx: BallContext, slot: Slot) -> Plan[None]:
    """One shot of `slot`: its ball loaded, the intent recorded (ball, its hit count), fire, evaluate."""
    st = ctx.state
    yield Checkpoint()
    steps.reshoots_left(ctx)
    yield from load(ctx, slot)
    index = len(st.shots) + 1
    yield Move(TARGET_FACE)
    aim_speed = slot.speed_m_s / st.aim_factor
    try:
        ctx.config.aim.pressure_for(aim_speed)
    except ConfigError as exc:
        raise RunAborted(f"{exc}: the measured speeds are far from the aim") from exc
    if ctx.confirm_fire and not (
        yield Ask(f"fire-{index}", f"Fire shot {index} (ball {slot.ball_id}) at {slot.speed_m_s:g} m/s?")
    ):
        raise RunAborted(f"the operator declined to fire shot {index}")
    yield Checkpoint()
    env = yield ReadEnvironment()  # the air at each shot: the lot's sensitivities to it are fitted
    yield Record(
        ev.ShotRequested(
            index=index,
            purpose=PURPOSE,
            location_in=TARGET_FACE,
            target_speed_m_s=slot.speed_m_s,
            aim_speed_m_s=aim_speed,
            ball=slot.ball_id,
            ball_hit=ball_hits(ctx, slot.ball_id) + 1,
            slot=slot.number,
            planned_hit=slot.planned_hit,
            temperature_c=env.temperature_c,
            humidity_pct=env.humidity_pct,
        )
    )
    fired = yield Fire(index, TARGET_FACE, aim_speed, slot.ball_id)
    if fired is None:
        return
    outcome: ShotOutcome = yield Evaluate(fired)
    yield Record(ev.ShotEvaluated(index=index, outcome=outcome))


def ball_test(ctx: PlanContext) -> Plan[RunVerdict | None]:
    """The ball test (ccor or ball-cor; their procedures differ only in data)."""
    assert isinstance(ctx, BallContext), "a ball test runs with a BallContext"
    if ctx.state.finished:
        return ctx.state.verdict
    yield from preflight(ctx)
    yield from start(ctx)
    yield from steps.check_budget(ctx)
    yield Checkpoint()
    yield from steps.environment(ctx)
    yield Checkpoint()
    yield Prepare(TARGET_FACE)
    yield from steps.resolve_pending(ctx)
    for slot in ctx.schedule():
        while not slot_done(ctx, slot):
            yield from shoot(ctx, slot)
    yield Checkpoint()
    verdict: RunVerdict = yield Decide()
    yield Record(ev.RunFinished(result=verdict))
    return verdict
