"""A lab's own procedure, from the standard steps: the public names for composing plans.

A plan is a generator that yields messages (`Record`, `Ask`, `Move`, `Fire`, ...) and receives
their answers; a step is a plan a bigger plan calls with `yield from`. `rig.certify(plan=...)`
runs a plan with the executor that owns run control, persistence and resume, after rehearsing it
against checking fakes (a dry run of the same plan). See docs/api.md, "Your own procedure".
"""

from __future__ import annotations

from rig.core import events
from rig.protocols.control import BudgetExceeded, RunAborted
from rig.protocols.plan import (
    Ask,
    Checkpoint,
    Decide,
    Evaluate,
    Fire,
    Fired,
    Move,
    Msg,
    Plan,
    PlanContext,
    PlanFactory,
    Prepare,
    Problem,
    ReadEnvironment,
    Record,
    TimePendulum,
)
from rig.protocols.steps import (
    certification,
    check_budget,
    choose_location,
    decide,
    environment,
    measure_moi,
    preflight,
    prepare,
    replace_ball,
    resolve_pending,
    ring_check,
    scan,
    shoot,
    start,
    valid_hits,
)

__all__ = [
    "Ask",
    "BudgetExceeded",
    "Checkpoint",
    "Decide",
    "Evaluate",
    "Fire",
    "Fired",
    "Move",
    "Msg",
    "Plan",
    "PlanContext",
    "PlanFactory",
    "Prepare",
    "Problem",
    "ReadEnvironment",
    "Record",
    "RunAborted",
    "TimePendulum",
    "certification",
    "check_budget",
    "choose_location",
    "decide",
    "environment",
    "events",
    "measure_moi",
    "preflight",
    "prepare",
    "replace_ball",
    "resolve_pending",
    "ring_check",
    "scan",
    "shoot",
    "start",
    "valid_hits",
]
