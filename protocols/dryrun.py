"""A dry run: the same plan as the real run, executed against checking fakes.

Nothing is armed, moved or recorded. The fakes answer every message with nominal values (lab
conditions mid-range, a pendulum period, every shot valid with a metric peaked at the middle of
the scan) and note what the rig could not do (an aim outside its calibration, a stage position
out of range); the plan's own Problem messages are listed and the plan goes on. Because it is the
plan itself that runs, the dry run cannot drift from the run.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.devices import (
    STAGE_RANGE_MM,
    BarrelCompression,
    Environment,
    GateConfig,
    GateCrossing,
    PendulumPeriod,
)
from rig.core.errors import ConfigError, DeviceError, RigError
from rig.core.events import RunEvent
from rig.core.outcomes import RunVerdict, ShotOutcome, Verdict
from rig.protocols.control import RunAborted, ScriptedOperator
from rig.protocols.executor import Executor
from rig.protocols.plan import Fired, Plan, PlanContext
from rig.protocols.procedure import Procedure
from rig.protocols.shot import ShotRecord
from rig.protocols.state import fold
from rig.protocols.steps import certification, plan_name

NOMINAL_GATES = GateConfig(gates=3, tick_ns=10.0, bits=32)
NOMINAL_PERIOD_S = 1.4  # a bat's swing on the pivot: a second and a half, give or take
MAX_MESSAGES = 100_000  # a plan still going after this many messages does not end


@dataclass
class CheckingRig:
    """Fake devices that answer nominally and note what the real rig could not do."""

    procedure: Procedure
    problems: list[str] = field(default_factory=list)
    stage: list[str] = field(default_factory=list)  # positions the stage cannot reach
    fired: list[tuple[float, float]] = field(default_factory=list)  # (impact from pivot m, aim m/s)

    def problem(self, text: str) -> None:
        """Note a problem once and go on."""
        if text not in self.problems:
            self.problems.append(text)

    def clear_fault(self) -> None:
        """No fault to clear."""

    def environment(self) -> Environment:
        """Mid-range lab conditions."""
        lim = self.procedure.environment
        return Environment(temperature_c=sum(lim.temperature_c) / 2, humidity_pct=sum(lim.humidity_pct) / 2)

    def time_pendulum(self, cycles: int) -> PendulumPeriod:
        """A nominal swing."""
        return PendulumPeriod(period_s=NOMINAL_PERIOD_S, amplitude_deg=5.0, cycles=cycles)

    def _stage(self, impact_from_pivot_m: float) -> None:
        lo, hi = STAGE_RANGE_MM
        mm = impact_from_pivot_m * 1000.0
        text = f"the stage cannot go to {mm:.0f} mm from the pivot (range {lo:g}-{hi:g} mm)"
        if not lo <= mm <= hi and text not in self.stage:
            self.stage.append(text)

    def prepare(self, impact_from_pivot_m: float) -> GateConfig:
        """Check the first stage position."""
        self._stage(impact_from_pivot_m)
        return NOMINAL_GATES

    def move(self, impact_from_pivot_m: float) -> None:
        """Check a stage position."""
        self._stage(impact_from_pivot_m)

    def fire(
        self,
        config: RigConfig,
        aim_speed_m_s: float,
        gates: GateConfig,
        live: Callable[[GateCrossing], None],
        ball: str | None = None,
    ) -> Fired:
        """Check the aim; a nominal record (six beam breaks, so the ball's hits count)."""
        self.fired.append((config.impact_from_pivot_m, aim_speed_m_s))
        try:
            pressure = config.aim.pressure_for(aim_speed_m_s)
        except ConfigError as exc:
            self.problem(str(exc))
            pressure = 0.0
        record = ShotRecord(
            shot_number=len(self.fired),
            target_speed_m_s=aim_speed_m_s,
            pressure_kpa=pressure,
            impact_from_pivot_m=config.impact_from_pivot_m,
            gate_positions_m=config.gates.positions_m,
            gate_config=gates,
            crossings=tuple(GateCrossing(g, 0) for g in (1, 2, 3, 3, 2, 1)),
            recoil_rad_s=None,
            notes=("dry run: nominal record, nothing fired",),
        )
        return Fired(record)

    def recover(self, exc: DeviceError) -> None:
        """Nothing fails in a dry run."""

    def evaluate(self, ctx: PlanContext, fired: Fired) -> ShotOutcome:
        """A valid shot whose metric peaks at the middle of the planned scan."""
        own = getattr(ctx, "rehearsed_shot", None)
        if own is not None:  # a context of its own kind (a ball test) says what its nominal shot is
            nominal: ShotOutcome = own()
            return nominal
        p = ctx.procedure
        planned = p.scan.locations_in()
        mid = (planned[0] + planned[-1]) / 2
        loc = ctx.state.shots[-1].location_in if ctx.state.shots else mid
        metric = p.limit * (0.9 - 0.01 * (loc - mid) ** 2)
        return ShotOutcome(
            metric_name=p.standard,
            metric=metric,
            u=0.0,
            valid=True,
            reasons=[],
            aim_factor=ctx.state.aim_factor,
            dry_run=True,
        )

    def compression(self) -> BarrelCompression:
        """A nominal reading that never changes (so a rehearsed break-in rolls its most)."""
        return BarrelCompression(force_lbf=240.0, displacement_in=0.040)

    def decide_stage(self, ctx: PlanContext, purpose: str, hoop_hz: float | None) -> RunVerdict:
        """A nominal stage below the limit."""
        p = ctx.procedure
        return RunVerdict(
            verdict=Verdict.PASS, metric=p.standard, limit=p.limit, mean=0.9 * p.limit, U=0.0, dry_run=True
        )

    def decide(self, ctx: PlanContext) -> RunVerdict:
        """No verdict: a dry run decides nothing."""
        own = getattr(ctx, "rehearsed_verdict", None)
        if own is not None:
            rehearsed: RunVerdict = own()
            return rehearsed
        p = ctx.procedure
        return RunVerdict(
            verdict=Verdict.PASS,
            metric=p.standard,
            limit=p.limit,
            dry_run=True,
            reason="dry run: nothing was measured",
        )


@dataclass(frozen=True)
class Rehearsal:
    """What a dry run found and did: the problems, the events it would record, the fakes' log."""

    problems: list[str]
    events: list[RunEvent]
    fired: list[tuple[float, float]]
    finished: bool
    stopped: str = ""  # why the plan would stop early (a run-time stop such as the re-shoot budget)

    def summary(self) -> str:
        """One line: what the plan would do if every shot were valid (its least)."""
        asked = [e for e in self.events if isinstance(e, ev.ShotRequested)]
        purposes = {p: [e.location_in for e in asked if e.purpose == p] for p in ("scan", "valid")}
        prompts = sum(1 for e in self.events if isinstance(e, ev.OperatorPrompted))
        timed = sum(1 for e in self.events if isinstance(e, ev.MoiMeasured) and e.result.timed)
        parts = [f"{len(asked)} shots at least"]
        if purposes["scan"]:
            scan = purposes["scan"]
            parts.append(f"{len(scan)} scanning {min(scan):g}-{max(scan):g} in")
        if purposes["valid"]:
            parts.append(f"{len(purposes['valid'])} valid hits at the maximum")
        parts.append(f"{prompts} operator prompts")
        if timed:
            parts.append("MOI timed on the pendulum")
        if self.stopped:
            parts.append(f"the run would stop: {self.stopped}")
        return ", ".join(parts)


def rehearse(
    procedure: Procedure,
    bat: BatSpec,
    config: RigConfig,
    plan: Callable[[PlanContext], Plan[Any]] = certification,
    history: list[RunEvent] | None = None,
    context: Callable[..., PlanContext] = PlanContext,
    **options: Any,
) -> Rehearsal:
    """Execute `plan` against checking fakes from the run's recorded `history` (a resumed run
    rehearses what is left of it); nothing is armed, moved or recorded. `context` builds the plan's
    context (a ball test's BallContext takes its lot among `options`)."""
    fakes = CheckingRig(procedure)
    events: list[RunEvent] = []

    def keep(event: RunEvent) -> None:
        events.append(event)

    ctx = context(
        procedure, bat, config, fold(history or []), who="dry run", plan_name=plan_name(plan), **options
    )
    executor = Executor(
        ctx, fakes, keep, operator=ScriptedOperator(True, "dry run"), max_messages=MAX_MESSAGES
    )
    finished, stopped = False, ""
    try:
        executor.run(plan)
        finished = True
    except RunAborted as exc:  # the real run stops there too, and says so in its record
        stopped = str(exc)
    except RigError as exc:
        fakes.problem(str(exc))
    # the stage's own limits back up the plan's location checks (a lab's plan may skip preflight)
    problems = fakes.problems or fakes.stage
    return Rehearsal(list(problems), events, list(fakes.fired), finished, stopped)


def dry_run(
    procedure: Procedure, bat: BatSpec, config: RigConfig, history: list[RunEvent] | None = None
) -> list[str]:
    """Everything in the procedure the rig or the bat cannot do, found before the cannon is armed."""
    return rehearse(procedure, bat, config, history=history).problems
