"""The lab's check session as a plan: the reference bat struck N times at one fixed location.

The certification's steps (rig.protocols.steps) without the scan: the procedure's single scan
location is recorded as the chosen one (LocationChosen, no scan means), then its valid hits are
shot and decided as a certification's are. Its runs are kind `check` in the store; the charts
(rig.quality) read their hits from RunFinished.
"""

from __future__ import annotations

from rig.core import events as ev
from rig.core.outcomes import RunVerdict
from rig.protocols.plan import Checkpoint, Plan, PlanContext, Problem, Record
from rig.protocols.steps import decide, opening, valid_hits
from rig.quality import CHECK_KIND

KIND = CHECK_KIND  # the store's kind of a check run


def check_session(ctx: PlanContext) -> Plan[RunVerdict | None]:
    """One check session: start, environment, MOI, the fixed location, its valid hits, decided."""
    if ctx.state.finished:
        return ctx.state.verdict
    scan = ctx.procedure.scan
    if scan.count != 1:
        yield Problem(f"a check procedure strikes one location: its scan has {scan.count} (from_in = to_in)")
    yield from opening(ctx)
    if ctx.state.best_location_in is None:
        yield Record(ev.LocationChosen(from_barrel_end_in=scan.from_in))
    yield from valid_hits(ctx)
    yield Checkpoint()
    return (yield from decide(ctx))
