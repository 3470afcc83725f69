"""The executor (run control, persistence, the stage, losses) and the dry run (the same plan, checked)."""

from __future__ import annotations

import contextlib
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.devices import GateConfig
from rig.core.errors import ConfigError, DeviceError, GarbledReply
from rig.protocols import steps
from rig.protocols.control import PlanError, RunAborted, RunControl, ScriptedOperator
from rig.protocols.dryrun import dry_run, rehearse
from rig.protocols.executor import Executor
from rig.protocols.plan import Checkpoint, Evaluate, Fire, Fired, Move, Plan, PlanContext, Prepare, Record
from rig.protocols.procedure import Procedure
from rig.protocols.state import fold
from rig.session import sim_config
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")


class FakeRig:
    """A backend written for these tests: counts stage moves, fails a fire on request."""

    def __init__(self, fail_fire: BaseException | None = None) -> None:
        self.moves: list[float] = []
        self.fail_fire = fail_fire
        self.recovered: list[DeviceError] = []

    def prepare(self, q: float) -> GateConfig:
        self.moves.append(q)
        return GateConfig(3, 10.0, 32)

    def move(self, q: float) -> None:
        self.moves.append(q)

    def fire(self, config: Any, aim: float, gates: GateConfig, live: Any, ball: str | None = None) -> Fired:
        if self.fail_fire is not None:
            raise self.fail_fire
        raise AssertionError("these tests fire only to fail")

    def recover(self, exc: DeviceError) -> None:
        self.recovered.append(exc)

    def problem(self, text: str) -> None:
        raise AssertionError(text)


def executor(backend: Any, control: RunControl | None = None) -> tuple[Executor, list[ev.RunEvent]]:
    recorded: list[ev.RunEvent] = []
    ctx = PlanContext(Procedure.load("bbcor"), BAT, sim_config("ideal", bat=BAT), fold([]))
    return Executor(ctx, backend, recorded.append, ScriptedOperator(), control), recorded


def one_shot(ctx: PlanContext) -> Plan[None]:
    yield Prepare(5.0)
    yield Record(ev.ShotRequested(index=1, purpose="scan", location_in=5.0))
    yield Fire(1, 5.0, 60.8)


def test_an_error_during_a_requested_shot_records_it_lost_and_stops() -> None:
    ex, recorded = executor(FakeRig(fail_fire=KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        ex.run(one_shot)
    lost = [e for e in recorded if isinstance(e, ev.ShotLost)]
    assert [x.index for x in lost] == [1] and "KeyboardInterrupt" in (lost[0].reason or "")
    assert ex.state.pending is None  # never fired again on resume


def test_a_device_error_loses_the_shot_recovers_and_commands_the_stage_again() -> None:
    rig = FakeRig(fail_fire=GarbledReply("cannon", "garbled reply"))

    def plan(ctx: PlanContext) -> Plan[Any]:
        yield from one_shot(ctx)
        yield Move(5.0)  # the same place: after a device error it is commanded again
        yield Move(5.0)  # and now it is known to be there

    ex, recorded = executor(rig)
    ex.run(plan)
    assert [type(e) for e in rig.recovered] == [GarbledReply]
    assert len(rig.moves) == 2  # prepare, then one move after the error; the second move skipped
    assert [e.kind for e in recorded if e.persisted][-2:] == ["ShotLost", "LocationSet"]


def test_an_abort_is_thrown_into_the_plan_which_may_handle_it() -> None:
    control = RunControl()
    control.abort("stop for the test")

    def plan(ctx: PlanContext) -> Plan[str]:
        try:
            yield Checkpoint()
        except RunAborted as exc:
            yield Record(ev.RunInterrupted(reason=str(exc)))
            return "handled"
        return "not aborted"

    ex, recorded = executor(FakeRig(), control)
    assert ex.run(plan) == "handled"
    assert [e.reason for e in recorded if isinstance(e, ev.RunInterrupted)] == ["stop for the test"]


def test_a_pause_holds_at_the_checkpoint_until_resumed() -> None:
    control = RunControl()
    control.pause()
    ex, recorded = executor(FakeRig(), control)
    threading.Timer(0.2, control.resume).start()
    t0 = time.monotonic()
    ex.run(lambda ctx: (yield Checkpoint()))
    assert time.monotonic() - t0 >= 0.15
    assert [e.kind for e in recorded] == ["RunPaused", "RunContinued"]


# -- the dry run -------------------------------------------------------------------------------
def test_the_dry_run_lists_every_problem_at_once() -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(
        update={
            "target_speed_m_s": 70.0,  # the ideal rig's aim table ends at 68 m/s
            "scan": p.scan.model_copy(update={"to_in": 30.0, "step_in": 5.0}),  # 30 in: past the pivot
            "moi": p.moi.model_copy(update={"source": "entered"}),
        }
    )
    bat = BAT.model_copy(update={"moi_kgm2": None})
    problems = dry_run(p, bat, sim_config("ideal", bat=bat))
    text = "\n".join(problems)
    assert "target speed 69.55 m/s is outside the aim calibration" in text
    assert "scan location 30 in from the tip is not on the bat beyond the pivot" in text
    assert "the bat file has no moi_kgm2" in text


def test_the_dry_run_fires_where_the_procedure_says_and_records_nothing(tmp_path: Path) -> None:
    p = Procedure.load("bbcor")
    found = rehearse(p, BAT, sim_config("ideal", bat=BAT))
    assert found.problems == [] and found.finished
    planned = p.scan.locations_in()
    at = [BAT.impact_from_pivot_m(x) for x in planned]
    scan_fires = [q for q, _ in found.fired[: len(planned)]]
    assert scan_fires == pytest.approx(at)
    centre = (planned[0] + planned[-1]) / 2  # the fakes' metric peaks mid-scan: valid hits go there
    mid = min(planned, key=lambda x: (abs(x - centre), x))
    valid = [q for q, _ in found.fired[len(planned) :]]
    assert len(valid) == p.hits.valid_hits and valid == pytest.approx(
        [BAT.impact_from_pivot_m(mid)] * len(valid)
    )
    assert not list(tmp_path.iterdir())


def test_the_dry_run_and_the_real_run_follow_one_plan(tmp_path: Path) -> None:
    """Up to the first shot's outcome the record of a real run and the rehearsal say the same."""
    p = Procedure.load("bbcor")
    config = sim_config("ideal", bat=BAT)
    found = rehearse(p, BAT, config)
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, p, BAT, config)
        session_facts = (ev.TRAFFIC, ev.INSTRUMENTS_IDENTIFIED)  # the dry run has no instruments
        real = [
            e.kind for e in store.entries(out.run_id) if e.kind in ev.BY_KIND and e.kind not in session_facts
        ]
    dry = [e.kind for e in found.events if e.persisted and e.kind != ev.TRAFFIC]
    upto = real.index(ev.SHOT_MEASURED) + 1
    assert real[:upto] == dry[:upto]
    assert real.count(ev.SHOT_REQUESTED) >= p.scan.count + p.hits.valid_hits
    assert dry.count(ev.SHOT_REQUESTED) == p.scan.count + p.hits.valid_hits


def test_a_custom_plan_runs_through_the_runner_and_its_steps_compose(tmp_path: Path) -> None:
    """A lab's own procedure: no scan, three valid hits at 6 in, from the standard steps."""
    from rig.core.events import LocationChosen

    def three_at_six(ctx: PlanContext) -> Plan[dict[str, Any]]:
        yield from steps.preflight(ctx)
        yield from steps.start(ctx)
        yield from steps.environment(ctx)
        yield from steps.prepare(ctx)
        yield from steps.measure_moi(ctx)
        yield Record(LocationChosen(from_barrel_end_in=6.0, bracketed=False, extra={"by": "lab plan"}))
        yield from steps.valid_hits(ctx)
        return (yield from steps.decide(ctx))

    p = Procedure.load("bbcor")
    p = p.model_copy(update={"hits": p.hits.model_copy(update={"valid_hits": 3})})
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, p, BAT, sim_config("ideal", bat=BAT), plan=three_at_six)
        entries = store.entries(out.run_id)
    assert out.status == "finished" and out.verdict.verdict in ("PASS", "FAIL")
    requested = [e.payload for e in entries if e.kind == ev.SHOT_REQUESTED]
    assert {r["purpose"] for r in requested} == {"valid"} and {r["location_in"] for r in requested} == {6.0}
    assert out.verdict.hits and len(out.verdict.hits) == 3


def test_the_cli_dry_run_says_what_the_plan_would_do(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rig.cli import main

    bat = str(ROOT / "protocols" / "examples" / "sample-bat.toml")
    args = ["certify", "--procedure", "bbcor", "--bat", bat, "--sim", "lab", "--dry-run"]
    assert main([*args, "--db", str(tmp_path / "r.db")]) == 0
    line = capsys.readouterr().err.strip()
    p = Procedure.load("bbcor")
    scan = p.scan.count * p.scan.hits_per_location  # 6 locations, 5.0-7.5 in
    shots = scan + p.hits.valid_hits
    prompts = 2 * shots + (shots - 1) // p.ball.replace_after_hits  # ring before and after, new balls
    assert line == (
        f"dry run: the procedure fits this rig and this bat ({shots} shots at least, {scan} scanning "
        f"{p.scan.from_in:g}-{p.scan.to_in:g} in, {p.hits.valid_hits} valid hits at the maximum, "
        f"{prompts} operator prompts, MOI timed on the pendulum)"
    )


# -- what the executor refuses a lab's own plan (found by a review of the plan refactor) --------
def _setup(ctx: PlanContext) -> Plan[None]:
    yield from steps.preflight(ctx)
    yield from steps.start(ctx)
    yield from steps.environment(ctx)
    yield from steps.prepare(ctx)  # the stage goes to the scan's first location, 5.0 in
    yield from steps.measure_moi(ctx)


def test_a_plan_that_forgets_to_move_still_fires_where_the_shot_was_requested(tmp_path: Path) -> None:
    """Checked on the wire: the stage position at each FIRE is the shot's recorded location."""
    from tests.protocols.wire import check_fires

    def forgets_the_move(ctx: PlanContext) -> Plan[dict[str, Any]]:
        yield from _setup(ctx)
        yield Record(ev.LocationChosen(from_barrel_end_in=7.0, bracketed=False))
        yield Record(ev.ShotRequested(index=1, purpose="valid", location_in=7.0))
        fired = yield Fire(1, 7.0, ctx.procedure.target_speed_m_s)  # no Move: the stage is at 5.0 in
        result = yield Evaluate(fired)
        yield Record(ev.ShotEvaluated(index=1, outcome=result))
        yield from steps.valid_hits(ctx)
        return (yield from steps.decide(ctx))

    p = Procedure.load("bbcor")
    p = p.model_copy(update={"hits": p.hits.model_copy(update={"valid_hits": 2})})
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, p, BAT, sim_config("ideal", bat=BAT), plan=forgets_the_move)
        entries = store.entries(out.run_id)
    assert out.status == "finished", out.reason
    assert set(check_fires(entries).values()) == {1}  # every shot once, each at its recorded location


def test_no_shot_fires_without_its_recorded_intent() -> None:
    rig = FakeRig(fail_fire=AssertionError("the cannon was fired"))

    def unrequested(ctx: PlanContext) -> Plan[None]:
        yield Prepare(5.0)
        yield Fire(1, 5.0, 60.8)

    ex, recorded = executor(rig)
    with pytest.raises(PlanError, match="no intent recorded"):
        ex.run(unrequested)
    assert not [e for e in recorded if isinstance(e, ev.ShotFired)]


def test_a_shot_is_never_requested_while_another_is_unresolved() -> None:
    def two_at_once(ctx: PlanContext) -> Plan[None]:
        yield Prepare(5.0)
        yield Record(ev.ShotRequested(index=1, purpose="scan", location_in=5.0))
        yield Record(ev.ShotRequested(index=2, purpose="scan", location_in=5.0))

    ex, recorded = executor(FakeRig())
    with pytest.raises(PlanError, match="shot 1 is unresolved"):
        ex.run(two_at_once)
    assert [e.kind for e in recorded if isinstance(e, ev.ShotRequested | ev.ShotLost)] == [
        "ShotRequested",
        "ShotLost",  # the first: stopped between its request and its outcome
    ]


def test_a_plan_that_catches_a_failed_fire_finds_the_shot_already_lost() -> None:
    seen: list[bool] = []

    def catches(ctx: PlanContext) -> Plan[None]:
        yield from one_shot(ctx)

    def wrapper(ctx: PlanContext) -> Plan[None]:
        try:
            yield from catches(ctx)
        except RuntimeError:
            seen.append(ctx.state.pending is None)

    ex, recorded = executor(FakeRig(fail_fire=RuntimeError("a bug in a driver")))
    ex.run(wrapper)
    assert seen == [True]  # lost before the plan saw the error: a resume never meets it unresolved
    assert [e.index for e in recorded if isinstance(e, ev.ShotLost)] == [1]


def test_an_abort_caught_by_a_plan_still_stops_the_next_fire() -> None:
    control = RunControl()
    rig = FakeRig(fail_fire=AssertionError("the cannon was fired after the abort"))

    def swallows(ctx: PlanContext) -> Plan[None]:
        yield Prepare(5.0)
        with contextlib.suppress(RunAborted):
            yield Checkpoint()
        yield Record(ev.ShotRequested(index=1, purpose="scan", location_in=5.0))
        yield Fire(1, 5.0, 60.8)

    ex, recorded = executor(rig, control)
    control.abort("operator stop")
    with pytest.raises(RunAborted, match="operator stop"):
        ex.run(swallows)
    assert [e.index for e in recorded if isinstance(e, ev.ShotLost)] == [1]


def test_a_run_resumes_only_with_the_plan_it_started_with(tmp_path: Path) -> None:
    def one_then_stop(ctx: PlanContext) -> Plan[dict[str, Any]]:
        yield from _setup(ctx)
        raise RunAborted("stop here for the test")

    p = Procedure.load("bbcor")
    config = sim_config("ideal", bat=BAT)
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, p, BAT, config, plan=one_then_stop)
        assert out.status == "interrupted"
        before = len(store.entries(out.run_id))
        with pytest.raises(ConfigError, match=r"started with the plan .*one_then_stop, not the standard"):
            certify(store, p, BAT, config, run_id=out.run_id)
        assert len(store.entries(out.run_id)) == before  # refused before anything was recorded


def test_a_plan_that_never_ends_is_a_dry_run_problem_not_a_hang() -> None:
    def forever(ctx: PlanContext) -> Plan[None]:
        while True:
            yield Checkpoint()

    found = rehearse(Procedure.load("bbcor"), BAT, sim_config("ideal", bat=BAT), forever)
    assert found.problems == ["the plan did not end within 100000 messages"]


def test_the_dry_run_lists_a_missing_calibration_with_the_other_problems(tmp_path: Path) -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(
        update={
            "calibration": str(tmp_path / "gone.json"),
            "moi": p.moi.model_copy(update={"source": "entered"}),
        }
    )
    bat = BAT.model_copy(update={"moi_kgm2": None})
    problems = dry_run(p, bat, sim_config("ideal", bat=bat))
    assert any("gone.json" in x for x in problems)
    assert any(
        x.startswith("procedure wants the MOI entered, but the bat file has no moi_kgm2") for x in problems
    )


def test_a_location_off_the_bat_is_named_once(tmp_path: Path) -> None:
    p = Procedure.load("bbcor")
    p = p.model_copy(
        update={"scan": p.scan.model_copy(update={"from_in": 28.0, "to_in": 30.0, "step_in": 2.0})}
    )
    problems = dry_run(p, BAT, sim_config("ideal", bat=BAT))
    assert problems == [
        "scan location 28 in from the tip is not on the bat beyond the pivot",
        "scan location 30 in from the tip is not on the bat beyond the pivot",
    ]
