"""A certification's steps as plans (rig.protocols.plan): each one small, each resumable from the state.

`certification` is the standard procedure (BESR, BBCOR, BBS differ only in their Procedure data):
preflight, start, environment, MOI, location scan, valid hits at the maximum, verdict, with the
ring checks and ball replacements each shot calls for. A lab composes its own from the same steps.
"""

from __future__ import annotations

from typing import Any

from rig.core import events as ev
from rig.core.bat import PIVOT_FROM_KNOB_IN, BatSpec
from rig.core.devices import STAGE_RANGE_MM, Environment
from rig.core.errors import ConfigError
from rig.core.outcomes import MoiResult, RunVerdict, ShotOutcome, Verdict
from rig.core.units import INCH
from rig.core.version import software
from rig.measure.moi import entered_budget, pendulum_moi
from rig.protocols import evaluate
from rig.protocols.ball_terms import BallTerms
from rig.protocols.control import BudgetExceeded, RunAborted
from rig.protocols.plan import (
    Ask,
    Checkpoint,
    ClearFault,
    Decide,
    Evaluate,
    Fire,
    Move,
    Plan,
    PlanContext,
    Prepare,
    Problem,
    ReadEnvironment,
    Record,
    TimePendulum,
)
from rig.protocols.procedure import Procedure


def location_problem(bat: BatSpec, loc_in: float) -> str | None:
    """Why the rig cannot hit the bat `loc_in` inches from the tip, or None if it can."""
    q_mm = bat.impact_from_pivot_m(loc_in) * 1000.0
    if not 0.0 < loc_in < bat.length_in - PIVOT_FROM_KNOB_IN:
        return f"scan location {loc_in:g} in from the tip is not on the bat beyond the pivot"
    lo, hi = STAGE_RANGE_MM
    if not lo <= q_mm <= hi:
        return f"scan location {loc_in:g} in needs the stage at {q_mm:.0f} mm (range {lo:g}-{hi:g} mm)"
    return None


# -- before anything moves ---------------------------------------------------------------------
def preflight(ctx: PlanContext) -> Plan[None]:
    """What the rig or the bat cannot do for this procedure, found before the cannon is armed."""
    p, config = ctx.procedure, ctx.config
    lo, hi = config.aim.speed_m_s[0], config.aim.speed_m_s[-1]
    for speed in (p.target_speed_m_s - p.speed_tolerance_m_s, p.target_speed_m_s + p.speed_tolerance_m_s):
        if not lo <= speed <= hi:
            yield Problem(f"target speed {speed:.2f} m/s is outside the aim calibration ({lo:g}-{hi:g} m/s)")
    for loc in p.scan.locations_in():
        problem = location_problem(ctx.bat, loc)
        if problem:
            yield Problem(problem)
    if p.hits.valid_hits > p.ball.replace_after_hits * 10:
        yield Problem("more valid hits than ten balls allow")


def start(ctx: PlanContext) -> Plan[None]:
    """Record the run's start (procedure, bat, rig, software, calibration), or its resumption."""
    if ctx.state.ended is not None:
        raise ConfigError("the run was ended without a verdict; start a new one", source="resume")
    recorded = (ctx.state.setup or {}).get("plan")
    if ctx.state.started and recorded != ctx.plan_name:
        raise ConfigError(
            f"the run was started with {_plan_words(recorded)}, not {_plan_words(ctx.plan_name)}: "
            "resume it with the same plan (rig.certify(resume=..., plan=...))",
            source="resume",
        )
    if not ctx.state.started:
        try:
            calibration = evaluate.run_calibration(ctx.procedure, ctx.config)
        except ConfigError as exc:  # a dry run lists it with the rest
            yield Problem(str(exc))
            calibration = None
        yield Record(
            ev.RunStarted(
                procedure=ctx.procedure.model_dump(mode="json"),
                bat=ctx.bat.model_dump(mode="json"),
                rig=ctx.config.model_dump(mode="json"),
                software=software(),
                calibration=calibration or None,
                ball=BallTerms.model_validate(ctx.options.get("ball") or {}).model_dump(mode="json"),
                plan=ctx.plan_name or None,
            )
        )
    else:
        yield Record(ev.RunResumed(shots_so_far=len(ctx.state.shots)))
    yield ClearFault()


def plan_name(plan: object) -> str | None:
    """How a lab's own plan is named in the record (module.function); None for the standard one."""
    if plan is certification:
        return None
    return f"{getattr(plan, '__module__', '?')}.{getattr(plan, '__qualname__', repr(plan))}"


def _plan_words(name: str | None) -> str:
    return f"the plan {name}" if name else "the standard procedure"


def check_budget(ctx: PlanContext) -> Plan[None]:
    """Record the operator's rig check (the budget starts again); stop if still over budget."""
    if ctx.rig_check is not None:
        yield Record(
            ev.RigChecked(
                who=ctx.rig_check["who"],
                why=ctx.rig_check["why"],
                invalid_shots_before=ctx.state.invalid_count,
            )
        )
    reshoots_left(ctx)


def reshoots_left(ctx: PlanContext) -> None:
    """Raise BudgetExceeded if more shots were invalid than the procedure allows since the last check."""
    limit = ctx.procedure.hits.max_reshoots
    if ctx.state.invalid_since_check > limit:
        since = "since the last rig check" if ctx.state.invalid_at_last_check else "in this run"
        raise BudgetExceeded(f"more than {limit} invalid shots {since}: check the rig")


def environment(ctx: PlanContext) -> Plan[None]:
    """Record the lab's temperature and humidity; stop if outside the procedure's limits."""
    env = yield ReadEnvironment()
    lim = ctx.procedure.environment
    ok_t = lim.temperature_c[0] <= env.temperature_c <= lim.temperature_c[1]
    ok_h = lim.humidity_pct[0] <= env.humidity_pct <= lim.humidity_pct[1]
    yield Record(
        ev.EnvironmentChecked(
            temperature_c=env.temperature_c, humidity_pct=env.humidity_pct, ok=ok_t and ok_h
        )
    )
    if not (ok_t and ok_h):
        raise RunAborted(
            f"lab conditions {env.temperature_c:.1f} C, {env.humidity_pct:.0f} % RH outside the "
            f"procedure's {lim.temperature_c} C, {lim.humidity_pct} % RH"
        )


def next_location(ctx: PlanContext) -> float:
    """Where the next shot goes: the first scan location short of hits, or the chosen one."""
    st, scan = ctx.state, ctx.procedure.scan
    if st.best_location_in is not None:
        return st.best_location_in
    for loc in st.scan_locations(scan.locations_in()):
        if len(st.valid_shots("scan", loc)) < scan.hits_per_location:
            return loc
    return scan.from_in


def prepare(ctx: PlanContext) -> Plan[None]:
    """Self-test the gates, lock the bat and put the stage where the next shot goes."""
    yield Prepare(next_location(ctx))


def resolve_pending(ctx: PlanContext) -> Plan[None]:
    """A shot an earlier session requested but never resolved is lost: it may have been fired."""
    pending = ctx.state.pending
    if pending is not None:
        yield Record(
            ev.ShotLost(
                index=pending.index,
                reason="the run stopped after this shot was requested and before its outcome was "
                "recorded; it may have been fired, so it is not fired again",
            )
        )


# -- the bat -----------------------------------------------------------------------------------
def measure_moi(ctx: PlanContext) -> Plan[None]:
    """The MOI and its derived u: entered with its stated u, or timed on the pendulum (F2398)."""
    p, bat = ctx.procedure, ctx.bat
    if p.moi.source == "entered":
        if bat.moi_kgm2 is None:
            yield Problem(
                "procedure wants the MOI entered, but the bat file has no moi_kgm2 (give moi_kgm2 and "
                "moi_u_kgm2, measured once on the pivot, as protocols/examples/reference-bat.toml does)"
            )
            return
        if bat.moi_u_kgm2 is None:
            yield Problem("an entered MOI needs its standard uncertainty: add moi_u_kgm2 to the bat file")
            return
        entered: dict[str, Any] = entered_budget(bat.moi_kgm2, bat.moi_u_kgm2).as_dict()
        yield Record(ev.MoiMeasured(result=MoiResult(**entered)))
        return
    if bat.balance_point_in is None:
        yield Problem("the pendulum MOI needs balance_point_in in the bat file")
        return
    timings = []
    for _ in range(p.moi.repeats):
        timings.append((yield TimePendulum(p.moi.cycles)))
    reading, found = pendulum_moi(timings, bat.mass_kg, bat.balance_point_in * INCH, ctx.config.pendulum)
    timed: dict[str, Any] = found.as_dict()
    yield Record(
        ev.MoiMeasured(
            result=MoiResult(
                **timed,
                period_s=sum(reading.periods_s) / len(reading.periods_s),
                periods_s=list(reading.periods_s),
                periods_host_u_s=list(reading.host_u_s) if reading.host_u_s else None,
                amplitude_deg=reading.amplitude_deg,
                cycles=reading.cycles,
            )
        )
    )


def scan_means(ctx: PlanContext) -> dict[float, float]:
    """Mean metric of the valid scan shots at each location shot so far."""
    means: dict[float, float] = {}
    for loc in sorted(ctx.state.scan_locations(ctx.procedure.scan.locations_in())):
        vals = [s.metric for s in ctx.state.valid_shots("scan", loc) if s.metric is not None]
        if vals:
            means[loc] = sum(vals) / len(vals)
    return means


def scan(ctx: PlanContext) -> Plan[None]:
    """Shoot the scan; while its maximum sits at an edge, extend it by one step (recorded)."""
    p = ctx.procedure
    while True:
        for loc in ctx.state.scan_locations(p.scan.locations_in()):
            while len(ctx.state.valid_shots("scan", loc)) < p.scan.hits_per_location:
                yield from shoot(ctx, loc, "scan")
        if ctx.state.best_location_in is not None:
            return
        step = extension(ctx)
        if step is None:
            return
        loc, reason = step
        yield Record(ev.ScanExtended(from_barrel_end_in=loc, impact_from_pivot_m=ctx.q(loc), reason=reason))


def extension(ctx: PlanContext) -> tuple[float, str] | None:
    """The next location beyond the scan's edge if the maximum is there and the rig may go on."""
    p = ctx.procedure
    means = scan_means(ctx)
    best = max(means, key=lambda k: means[k])
    planned = p.scan.locations_in()
    reach = planned[0] - p.scan.extend_in - 1e-9, planned[-1] + p.scan.extend_in + 1e-9
    for sign, side in ((-1.0, "tip"), (1.0, "handle")):
        if any(sign * (x - best) > 0 for x in means):
            continue  # a lower mean on this side already
        nxt = round(best + sign * p.scan.step_in, 6)
        if reach[0] <= nxt <= reach[1] and location_problem(ctx.bat, nxt) is None:
            return nxt, (
                f"the highest mean {p.standard} so far ({means[best]:.4f}) is at {best:g} in, "
                f"the scan's edge towards the {side}: the maximum is not bracketed yet"
            )
    return None  # bracketed, or the procedure and the bat allow no further step


def choose_location(ctx: PlanContext) -> Plan[None]:
    """Record the scan's maximum as the location to certify at (an unbracketed edge needs a yes)."""
    p = ctx.procedure
    means = scan_means(ctx)
    best = max(means, key=lambda k: means[k])
    bracketed = any(x < best for x in means) and any(x > best for x in means)
    accepted_by = None
    if not bracketed:
        text = (
            f"The highest mean {p.standard} ({means[best]:.4f}) is at {best:g} in from the "
            f"tip, the edge of the scan (extended as far as the procedure and the bat allow): the "
            f"maximum is not bracketed. Certify at {best:g} in anyway?"
        )
        if not (yield Ask("edge-location", text)):
            raise RunAborted(
                f"the location of maximum performance is not bracketed (highest mean at {best:g} in, "
                "the scan's edge): widen the procedure's scan or scan.extend_in"
            )
        accepted_by = ctx.who
    yield Record(
        ev.LocationChosen(
            from_barrel_end_in=best,
            mean_metric=means[best],
            scan={str(k): v for k, v in means.items()},
            bracketed=bracketed,
            accepted_by=accepted_by,
        )
    )


def valid_hits(ctx: PlanContext) -> Plan[None]:
    """Shoot at the chosen location until the procedure's valid hits are in."""
    best = ctx.state.best_location_in
    assert best is not None, "valid_hits follows choose_location"
    while len(ctx.state.valid_shots("valid", best)) < ctx.procedure.hits.valid_hits:
        yield from shoot(ctx, best, "valid")


def decide(ctx: PlanContext) -> Plan[RunVerdict]:
    """Decide the verdict from the valid hits and record it; returns it."""
    verdict: RunVerdict = yield Decide()
    yield Record(ev.RunFinished(result=verdict))
    return verdict


# -- one shot ----------------------------------------------------------------------------------
def replace_ball(ctx: PlanContext) -> Plan[None]:
    """Ask for a new ball once the current one has had its hits."""
    st = ctx.state
    if st.ball_hits >= ctx.procedure.ball.replace_after_hits:
        lot = ctx.recorded_ball()
        if lot.get("balls") is not None and ctx.lot_ball_number(st.ball_number + 1) > int(lot["balls"]):
            raise RunAborted(
                f"lot {lot.get('lot')} has {lot['balls']} balls and every one has had its hits: "
                "name a larger lot (this run resumes with the same lot only)"
            )
        if not (
            yield Ask("ball", f"Replace the ball (ball {st.ball_number} has {st.ball_hits} hits). Done?")
        ):
            raise RunAborted("ball not replaced")
        yield Record(ev.BallReplaced(ball_number=st.ball_number + 1))


def outside_window(p: Procedure, lot: dict[str, Any], temp_c: float, rh_pct: float) -> None:
    """Stop (resumable) before a shot when the lab's air is outside the lot's conditioning window."""
    win_c, win_pct = p.ball.air_window_c, p.ball.air_window_pct
    t0, rh0 = float(lot.get("temp_c", 21.0)), float(lot.get("rh_pct", 50.0))
    off_c = win_c is not None and abs(temp_c - t0) > win_c
    off_pct = win_pct is not None and abs(rh_pct - rh0) > win_pct
    if off_c or off_pct:
        window = " and ".join(
            [f"{t0:g} +- {win_c:g} C"] * (win_c is not None)
            + [f"{rh0:g} +- {win_pct:g} % RH"] * (win_pct is not None)
        )
        raise RunAborted(
            f"the lab's air ({temp_c:.1f} C, {rh_pct:.0f} % RH) is outside lot {lot.get('lot')}'s "
            f"conditioning window ({window}): resume when it is back"
        )


def ring_check(ctx: PlanContext, prompt_id: str, text: str, index: int) -> Plan[None]:
    """Ask for a ring check (if the procedure has them); a failed one ends the run with FAIL."""
    if ctx.procedure.ring_check and not (yield Ask(prompt_id, text)):
        p = ctx.procedure
        reason = f"ring check failed at shot {index}: barrel deformed"
        yield Record(
            ev.RunFinished(
                result=RunVerdict(verdict=Verdict.FAIL, metric=p.standard, limit=p.limit, reason=reason)
            )
        )
        raise RunAborted(reason)


# how a fire prompt names a shot's purpose: "(valid)" read like a verdict before the shot
PURPOSE_WORDS = {"scan": "scan", "valid": "for the result"}


def shoot(ctx: PlanContext, loc_in: float, purpose: str) -> Plan[None]:
    """One shot at `loc_in` from the tip: checks, intent recorded, fire, evaluate, review."""
    p, st = ctx.procedure, ctx.state
    yield Checkpoint()
    reshoots_left(ctx)
    yield from replace_ball(ctx)
    index = len(st.shots) + 1
    yield from ring_check(
        ctx, f"ring-before-{index}", "Ring check: does the ring pass over the whole bat?", index
    )
    yield Move(loc_in)
    aim_speed = p.target_speed_m_s / st.aim_factor
    try:  # before the shot is requested: an aim the cannon cannot give stops the run, nothing fired
        ctx.config.aim.pressure_for(aim_speed)
    except ConfigError as exc:
        raise RunAborted(
            f"{exc}: the measured speeds are far from the aim (gate positions in the rig config wrong?)"
        ) from exc
    what = PURPOSE_WORDS.get(purpose, purpose)
    if ctx.confirm_fire and not (
        yield Ask(f"fire-{index}", f"Fire shot {index} ({what}) at {loc_in:g} in from the tip?")
    ):
        raise RunAborted(f"the operator declined to fire shot {index}")
    yield Checkpoint()
    air: Environment | None = None
    lot = ctx.recorded_ball()
    if lot.get("lot"):  # a named lot: the air at each shot, for its terms and its conditioning window
        air = yield ReadEnvironment()
        outside_window(p, lot, air.temperature_c, air.humidity_pct)
    yield Record(
        ev.ShotRequested(
            index=index,
            purpose=purpose,
            location_in=loc_in,
            target_speed_m_s=p.target_speed_m_s,
            aim_speed_m_s=aim_speed,
            temperature_c=None if air is None else air.temperature_c,
            humidity_pct=None if air is None else air.humidity_pct,
        )
    )
    fired = yield Fire(index, loc_in, aim_speed, ctx.ball_id())
    if fired is None:
        return  # lost: recorded by the executor, never fired again
    outcome: ShotOutcome = yield Evaluate(fired)
    yield Record(ev.ShotEvaluated(index=index, outcome=outcome))
    shot = st.shots[-1]
    if shot.valid and ctx.review_shots:
        metric = f"{p.standard} {shot.metric:.4f}"
        if not (yield Ask(f"review-{index}", f"Accept shot {index} ({metric})? n rejects it: re-shoot")):
            yield Record(
                ev.ShotOverruled(index=index, reason="rejected by the operator on review", who=ctx.who)
            )
    yield from ring_check(
        ctx, f"ring-after-{index}", "Ring check after the hit: does the ring still pass?", index
    )


# -- the standard procedure --------------------------------------------------------------------
def opening(ctx: PlanContext) -> Plan[None]:
    """What every run of a bat does before its first shot: checks, start, air, stage, MOI."""
    yield from preflight(ctx)
    yield from start(ctx)
    yield from check_budget(ctx)
    yield Checkpoint()
    yield from environment(ctx)
    yield Checkpoint()
    yield from prepare(ctx)
    yield from resolve_pending(ctx)
    if ctx.state.moi is None:
        yield from measure_moi(ctx)


def certification(ctx: PlanContext) -> Plan[RunVerdict | None]:
    """The certification procedure of NCAA BESR, BBCOR and BBS (their Procedure data differ)."""
    if ctx.state.finished:
        return ctx.state.verdict
    yield from opening(ctx)
    yield from scan(ctx)
    if ctx.state.best_location_in is None:
        yield from choose_location(ctx)
    yield from valid_hits(ctx)
    yield Checkpoint()
    return (yield from decide(ctx))
