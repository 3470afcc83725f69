"""The procedure's steps as plans, driven message by message by a driver written here.

The driver answers each message itself (no executor, no devices), so these tests say what a step
asks for and in what order, independently of how the executor carries it out.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from pathlib import Path
from typing import Any

import pytest

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.devices import Environment, PendulumPeriod
from rig.protocols import steps
from rig.protocols.control import BudgetExceeded, RunAborted
from rig.protocols.plan import (
    Ask,
    Decide,
    Evaluate,
    Fire,
    Fired,
    Move,
    Msg,
    PlanContext,
    Problem,
    ReadEnvironment,
    Record,
    TimePendulum,
)
from rig.protocols.procedure import Procedure
from rig.protocols.state import RunState, fold
from rig.session import sim_config

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
LAB = Environment(22.0, 50.0)


def ctx_for(
    procedure: Procedure | None = None, history: list[ev.RunEvent] | None = None, **kw: Any
) -> PlanContext:
    p = procedure or Procedure.load("bbcor")
    return PlanContext(p, BAT, sim_config("ideal", bat=BAT), fold(history or []), **kw)


class Driver:
    """Answers a plan's messages from a script; folds Records into the context's state."""

    def __init__(
        self,
        ctx: PlanContext,
        metric: Callable[[float], float] = lambda loc: 0.45,
        answers: dict[str, bool] | None = None,
        env: Environment = LAB,
    ) -> None:
        self.ctx, self.metric, self.answers, self.env = ctx, metric, answers or {}, env
        self.log: list[Msg] = []

    def answer(self, msg: Msg) -> Any:
        self.log.append(msg)
        if isinstance(msg, Record):
            self.ctx.state.apply(msg.event)
            return None
        if isinstance(msg, Ask):
            return self.answers.get(msg.prompt_id.split("-")[0], True)
        if isinstance(msg, ReadEnvironment):
            return self.env
        if isinstance(msg, TimePendulum):
            return PendulumPeriod(1.5, 5.0, msg.cycles)
        if isinstance(msg, Fire):
            self.ctx.state.apply(ev.ShotFired(index=msg.index, crossings=[{"gate": 1}]))
            return Fired(record=None)  # type: ignore[arg-type]  # the driver evaluates by location
        if isinstance(msg, Evaluate):
            loc = self.ctx.state.shots[-1].location_in
            return ev.ShotOutcome(metric=self.metric(loc), valid=True, aim_factor=1.0)
        if isinstance(msg, Decide):
            return ev.RunVerdict(verdict="PASS", metric="bbcor", limit=0.5)
        return None

    def run(self, plan: Generator[Msg, Any, Any]) -> Any:
        value: Any = None
        while True:
            try:
                msg = plan.send(value)
            except StopIteration as stop:
                return stop.value
            value = self.answer(msg)

    def kinds(self) -> list[str]:
        return [m.event.kind if isinstance(m, Record) else type(m).__name__ for m in self.log]


def test_one_shot_records_its_intent_before_it_fires_and_its_outcome_after() -> None:
    ctx = ctx_for()
    drv = Driver(ctx)
    drv.run(steps.shoot(ctx, 6.0, "scan"))
    assert drv.kinds() == [
        "Checkpoint",
        "Ask",  # ring check before
        "Move",
        "Checkpoint",
        "ShotRequested",
        "Fire",
        "Evaluate",
        "ShotMeasured",
        "Ask",  # ring check after
    ]
    move = next(m for m in drv.log if isinstance(m, Move))
    fire = next(m for m in drv.log if isinstance(m, Fire))
    assert move.location_in == fire.location_in == 6.0  # fired where it moved
    assert ctx.state.shots[0].location_in == 6.0 and ctx.state.shots[0].valid


def test_a_failed_ring_check_records_fail_then_stops() -> None:
    ctx = ctx_for()
    drv = Driver(ctx, answers={"ring": False})
    with pytest.raises(RunAborted, match="ring check failed at shot 1"):
        drv.run(steps.shoot(ctx, 6.0, "scan"))
    assert not any(isinstance(m, Fire) for m in drv.log)  # failed before: nothing fired
    assert ctx.state.finished and ctx.state.verdict.verdict == "FAIL"


def test_the_ball_is_replaced_after_its_hits() -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(update={"ball": p.ball.model_copy(update={"replace_after_hits": 2})})
    ctx = ctx_for(p)
    drv = Driver(ctx)
    for _ in range(3):
        drv.run(steps.shoot(ctx, 6.0, "scan"))
    balls = [m.event for m in drv.log if isinstance(m, Record) and isinstance(m.event, ev.BallReplaced)]
    assert [b.ball_number for b in balls] == [2]  # after hits 1 and 2, before hit 3
    asked = [m.prompt_id for m in drv.log if isinstance(m, Ask)]
    assert asked.index("ball") == asked.index("ring-before-3") - 1


def test_a_declined_ball_stops_before_anything_is_requested() -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(update={"ball": p.ball.model_copy(update={"replace_after_hits": 1})})
    ctx = ctx_for(p)
    Driver(ctx).run(steps.shoot(ctx, 6.0, "scan"))
    drv = Driver(ctx, answers={"ball": False})
    with pytest.raises(RunAborted, match="ball not replaced"):
        drv.run(steps.shoot(ctx, 6.0, "scan"))
    assert len(ctx.state.shots) == 1


def test_environment_out_of_limits_is_recorded_then_stops() -> None:
    ctx = ctx_for()
    drv = Driver(ctx, env=Environment(30.0, 50.0))  # the procedure allows 18-26 C
    with pytest.raises(RunAborted, match=r"30\.0 C"):
        drv.run(steps.environment(ctx))
    assert ctx.state.environment == {"temperature_c": 30.0, "humidity_pct": 50.0, "ok": False}


def test_the_scan_extends_towards_a_maximum_at_its_edge_and_brackets_it() -> None:
    # metric falls from the tip: the maximum is beyond the planned scan's first location (5.0 in)
    ctx = ctx_for()
    drv = Driver(ctx, metric=lambda loc: 0.5 - 0.01 * abs(loc - 4.5))
    drv.run(steps.scan(ctx))
    extended = [m.event for m in drv.log if isinstance(m, Record) and isinstance(m.event, ev.ScanExtended)]
    assert [e.from_barrel_end_in for e in extended] == [4.5, 4.0]  # 4.5 still the edge; 4.0 brackets it
    drv.run(steps.choose_location(ctx))
    assert ctx.state.best_location_in == 4.5 and ctx.state.location.bracketed is True


def test_an_unbracketed_maximum_needs_the_operators_yes() -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(update={"scan": p.scan.model_copy(update={"extend_in": 0.0})})
    ctx = ctx_for(p)
    drv = Driver(ctx, metric=lambda loc: 0.5 - 0.01 * loc, answers={"edge": False})
    drv.run(steps.scan(ctx))
    with pytest.raises(RunAborted, match="not bracketed"):
        drv.run(steps.choose_location(ctx))
    assert ctx.state.best_location_in is None


def test_the_reshoot_budget_stops_a_shot_before_it_is_requested() -> None:
    p = Procedure.load("bbcor")
    limit = p.hits.max_reshoots
    history: list[ev.RunEvent] = []
    for i in range(1, limit + 2):
        history += [
            ev.ShotRequested(index=i, purpose="scan", location_in=5.0),
            ev.ShotLost(index=i, reason="test"),
        ]
    ctx = ctx_for(p, history)
    drv = Driver(ctx)
    with pytest.raises(BudgetExceeded):
        drv.run(steps.shoot(ctx, 5.0, "scan"))
    assert not any(isinstance(m, Record) for m in drv.log)


def test_a_resumed_plan_goes_on_where_the_record_stops() -> None:
    """Scan done and location chosen in the record: the plan shoots only valid hits, at the choice."""
    ctx = ctx_for()
    first = Driver(ctx, metric=lambda loc: 0.5 - 0.01 * abs(loc - 6.0))
    first.run(steps.scan(ctx))
    first.run(steps.choose_location(ctx))
    history = [m.event for m in first.log if isinstance(m, Record)]
    history.append(ev.ShotRequested(index=len(ctx.state.shots) + 1, purpose="valid", location_in=6.0))
    resumed = ctx_for(history=[ev.RunStarted(procedure={}, bat={}, rig={}), *history])
    resumed.state.moi = {"moi_kgm2": 0.2}
    drv = Driver(resumed)
    result = drv.run(steps.certification(resumed))
    assert result.verdict == "PASS"
    lost = [m.event for m in drv.log if isinstance(m, Record) and isinstance(m.event, ev.ShotLost)]
    assert [x.index for x in lost] == [history[-1].index]  # the pending one, never fired
    fires = [m for m in drv.log if isinstance(m, Fire)]
    assert fires and {f.location_in for f in fires} == {6.0}  # no scan shot again
    assert fires[0].index == history[-1].index + 1
    assert len(fires) == resumed.procedure.hits.valid_hits
    assert not any(isinstance(m, Record) and isinstance(m.event, ev.RunStarted) for m in drv.log)


def test_moi_from_the_pendulum_times_the_procedures_repeats() -> None:
    ctx = ctx_for()
    drv = Driver(ctx)
    drv.run(steps.measure_moi(ctx))
    timed = [m for m in drv.log if isinstance(m, TimePendulum)]
    assert len(timed) == ctx.procedure.moi.repeats and {t.cycles for t in timed} == {ctx.procedure.moi.cycles}
    # I = m g d T^2 / (4 pi^2) at small amplitude: the recorded MOI is that of the answered period
    d = (BAT.balance_point_in - 6.0) * 0.0254
    closed = BAT.mass_kg * ctx.config.pendulum.gravity_m_s2 * d * 1.5**2 / (4 * math.pi**2)
    assert ctx.state.moi.moi_kgm2 == pytest.approx(closed, rel=2e-3)  # 5 deg amplitude correction


def test_missing_bat_data_is_a_problem_not_a_crash() -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(update={"moi": p.moi.model_copy(update={"source": "entered"})})
    ctx = PlanContext(p, BAT.model_copy(update={"moi_kgm2": None}), sim_config("ideal", bat=BAT), RunState())
    drv = Driver(ctx)
    drv.run(steps.measure_moi(ctx))
    (problem,) = [m.text for m in drv.log if isinstance(m, Problem)]
    assert problem.startswith("procedure wants the MOI entered, but the bat file has no moi_kgm2 (give")
    assert ctx.state.moi is None
