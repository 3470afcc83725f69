"""Runs a certification procedure on a rig's devices: the standard plan, its executor, its dry run.

The runner is restartable: its progress is a fold of the recorded events (rig.protocols.state), so
`run()` on a resumed event list continues at the next unfired shot. A shot whose intent was
recorded but whose outcome was not (a crash between FIRE and the record) is marked lost, never
fired again. The procedure's steps are plans (rig.protocols.steps), carried out by rig.protocols.executor;
the dry run (rig.protocols.dryrun) executes the same plan against checking fakes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.devices import Cannon, Clamp, Gates
from rig.core.errors import ConfigError
from rig.core.events import RunEvent
from rig.core.run_phase import RunPhase, refuse
from rig.protocols.control import BudgetExceeded, Operator, RunAborted, RunControl, ScriptedOperator
from rig.protocols.dryrun import dry_run, rehearse
from rig.protocols.executor import Executor, LiveRig
from rig.protocols.plan import PlanContext, PlanFactory
from rig.protocols.procedure import Procedure
from rig.protocols.state import RunState, fold
from rig.protocols.steps import certification, location_problem, plan_name

__all__ = [
    "BudgetExceeded",
    "Operator",
    "RunAborted",
    "RunControl",
    "Runner",
    "ScriptedOperator",
    "dry_run",
    "location_problem",
]


class Runner:
    """Executes one procedure's plan for one bat; every persisted event goes to `emit` before it goes on."""

    def __init__(
        self,
        procedure: Procedure,
        bat: BatSpec,
        config: RigConfig,
        cannon: Cannon,
        gates: Gates,
        clamp: Clamp,
        emit: Callable[[RunEvent], None],
        operator: Operator | None = None,
        history: list[RunEvent] | None = None,
        drain_traffic: Callable[[], list[dict[str, Any]]] | None = None,
        control: RunControl | None = None,
        confirm_fire: bool = False,
        review_shots: bool = False,
        rig_check: dict[str, str] | None = None,
        plan: PlanFactory = certification,
        options: dict[str, Any] | None = None,
    ) -> None:
        self.p, self.bat, self.config, self.plan = procedure, bat, config, plan
        self.history = list(history or [])
        operator = operator or ScriptedOperator()
        self.ctx = PlanContext(
            procedure,
            bat,
            config,
            fold(self.history),
            who=getattr(operator, "who", "operator"),
            confirm_fire=confirm_fire,
            review_shots=review_shots,
            rig_check=rig_check,
            plan_name=plan_name(plan),
            options=dict(options or {}),
        )
        self.executor = Executor(
            self.ctx, LiveRig(cannon, gates, clamp), emit, operator, control, drain_traffic
        )

    @property
    def state(self) -> RunState:
        """The run's folded state."""
        return self.ctx.state

    @property
    def control(self) -> RunControl:
        """Pause, resume, abort."""
        return self.executor.control

    def flush_traffic(self) -> None:
        """Record device traffic not yet attached to a shot (e.g. before an interruption)."""
        self.executor.flush_traffic()

    def run(self, rehearse_first: bool = True) -> dict[str, Any]:
        """Run (or resume) to the verdict; returns the RunFinished payload.

        The plan is first rehearsed against checking fakes: every problem is named before anything
        is armed (ConfigError listing them all). A caller that has just rehearsed the same plan from
        the same record (rig.certification, before it takes the run lock) passes False.
        """
        phase = self.state.phase
        if phase is RunPhase.FINISHED:
            return dict(self.state.verdict or {})
        if refuse(ev.RUN_STARTED, phase) and refuse(ev.RUN_RESUMED, phase):  # ended: nothing may follow
            raise ConfigError("the run was ended without a verdict; start a new one", source="resume")
        problems = (
            rehearse(
                self.p, self.bat, self.config, self.plan, self.history, options=dict(self.ctx.options)
            ).problems
            if rehearse_first
            else []
        )
        if problems:
            raise ConfigError("; ".join(problems), source="dry run")
        return self.executor.run(self.plan)
