"""Runs a plan on a rig's devices to its result, and the names a run's callers steer it with.

A run is restartable: its progress is a fold of the recorded events (rig.protocols.state), so a plan
run on a resumed record continues at the next unfired shot. A shot whose intent was recorded but
whose outcome was not (a crash between FIRE and the record) is marked lost, never fired again. The
procedure's steps are plans (rig.protocols.steps), carried out by rig.protocols.executor; the dry
run (rig.protocols.dryrun) executes the same plan against checking fakes, once per run, in the
application layer (rig.certification.prepare) before anything is recorded or opened.
"""

from __future__ import annotations

from rig.core import events as ev
from rig.core.errors import ConfigError
from rig.core.outcomes import RunVerdict
from rig.core.run_phase import RunPhase, refuse
from rig.protocols.control import BudgetExceeded, Operator, RunAborted, RunControl, ScriptedOperator
from rig.protocols.dryrun import dry_run
from rig.protocols.executor import Executor
from rig.protocols.plan import PlanFactory
from rig.protocols.steps import location_problem

__all__ = [
    "BudgetExceeded",
    "Operator",
    "RunAborted",
    "RunControl",
    "ScriptedOperator",
    "dry_run",
    "location_problem",
    "run_to_verdict",
]


def run_to_verdict(executor: Executor, plan: PlanFactory) -> RunVerdict | None:
    """Run (or resume) `plan` to the verdict and return it. A finished run answers its recorded
    verdict; a run ended without one is refused (ConfigError)."""
    state = executor.state
    phase = state.phase
    if phase is RunPhase.FINISHED:
        return state.verdict
    if refuse(ev.RUN_STARTED, phase) and refuse(ev.RUN_RESUMED, phase):  # ended: nothing may follow
        raise ConfigError("the run was ended without a verdict; start a new one", source="resume")
    return executor.run(plan)
