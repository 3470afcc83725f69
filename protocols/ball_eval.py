"""A ball test's measurement: each hit's COR (CCOR) at the impact point, and the lot's result.

A hit's COR is the rebound speed over the inbound speed at the target's face, both corrected for
air drag from the gates to the impact point exactly as the bat procedures correct them
(rig.measure.model), with the hit's GUM budget (timing per hit; gate positions, drag and air
shared by every hit of the run). The lot's result (`lot_result`) is derived from the valid hits
alone, so anyone can recompute it from the run's record (`rig verify` does).
"""

from __future__ import annotations

import math
import statistics
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.core.ball import BallLot, CcorPoint, LotResult, SpeedPoint
from rig.core.config import RigConfig
from rig.core.errors import RigError
from rig.core.outcomes import RunVerdict, ShotOutcome, Verdict
from rig.measure.model import ShotInputs, inbound_at_impact
from rig.measure.speeds import ShotDataError, shot_speeds, split_passes
from rig.measure.uncertainty import budget
from rig.measure.validity import ValidityLimits, check_shot
from rig.protocols.ball_procedure import BallProcedure
from rig.protocols.outcome import concluded, learned_aim, no_data
from rig.protocols.run_inputs import air_density, drag_inputs, uncertainty_model
from rig.protocols.shot import ShotRecord
from rig.protocols.state import RunState, ShotEntry

NO_MOI = 1.0  # a rigid fixed target has no MOI; the budget's e_A does not depend on it


def quantity(p: BallProcedure) -> str:
    """What the test measures: "ccor" on the cylinder, "cor" on the plate."""
    return "ccor" if p.test == "ccor" else "cor"


def shot(
    record: ShotRecord, p: BallProcedure, state: RunState, failure: str, config: RigConfig
) -> ShotOutcome:
    """Speeds at the impact point, COR (CCOR) with its u, and validity of one fired ball."""
    requested = state.shots[-1].requested if state.shots else None
    asked = None if requested is None else requested.target_speed_m_s
    target_speed = float(p.speeds_m_s[0] if asked is None else asked)
    out: dict[str, Any] = {
        "metric_name": quantity(p),
        "metric": None,
        "u": None,
        "ball": None if requested is None else requested.ball,
        "ball_hit": None if requested is None else requested.ball_hit,
        "target_speed_m_s": target_speed,
        "aim_factor": state.aim_factor,
    }
    try:
        passes = split_passes(record.crossings, record.gate_config)
        speeds = shot_speeds(passes, record.gate_positions_m, record.gate_config)
    except ShotDataError as exc:
        return no_data(out, exc)
    air = air_density(config, state)
    drag = drag_inputs(config, air)
    q = record.impact_from_pivot_m
    v_at_target = None
    if speeds.inbound is not None:
        v_at_target = inbound_at_impact(
            passes, record.gate_positions_m, record.gate_config, p.ball.mass_kg, drag
        )
        taught = min(state.aim_shots, _shots_at(state, target_speed))  # a new speed: its own mean
        out["aim_factor"] = learned_aim(state.aim_factor, target_speed, v_at_target, taught)
        out["aim_shots"] = taught + 1
    limits = ValidityLimits(speed_tolerance_m_s=p.speed_tolerance_m_s)
    reasons = check_shot(
        speeds,
        passes,
        target_speed,
        None,  # a fixed target does not recoil
        q,
        NO_MOI,
        p.ball.mass_kg,
        limits,
        positions_m=record.gate_positions_m,
        inbound_at_impact_m_s=v_at_target,
    )
    out["inbound_speed_m_s"], out["rebound_speed_m_s"] = speeds.inbound, speeds.rebound
    if speeds.inbound is not None and speeds.rebound is not None and speeds.rebound > 0:
        inputs = ShotInputs.from_passes(
            passes, record.gate_positions_m, record.gate_config, q, NO_MOI, p.ball.mass_kg, drag
        )
        hit = budget(inputs, uncertainty_model(p, config, state, air))  # type: ignore[arg-type]
        out.update(
            metric=hit.value("e_a"),
            u=hit.u_of("e_a"),
            u_systematic=math.sqrt(max(0.0, hit.systematic_variance("e_a"))),
            inbound_at_impact_m_s=hit.value("v_in"),
            rebound_at_impact_m_s=hit.value("v_out"),
            budget=hit.as_dict(),
        )
    return concluded(out, reasons, failure)


def _shots_at(state: RunState, target_speed: float) -> int:
    """How many evaluated shots just before this one were aimed at `target_speed` (a ccor test's
    speeds each need their own aim factor: the aim table may be off by another ratio at each)."""
    count = 0
    for s in reversed(state.shots[:-1]):
        if s.outcome is None:
            continue
        asked = None if s.requested is None else s.requested.target_speed_m_s
        if float(-1.0 if asked is None else asked) != target_speed:
            break
        count += 1
    return count


def points(shots: Sequence[ShotEntry]) -> list[CcorPoint]:
    """The valid hits as points (speed at the impact point, COR, u, ball, the ball's hit count)."""
    found = []
    for s in shots:
        m, r = s.outcome, s.requested
        if not s.valid or m is None or m.metric is None or r is None:
            continue
        found.append(
            CcorPoint(
                speed_m_s=float(_known(m.inbound_at_impact_m_s)),
                target_speed_m_s=float(_known(r.target_speed_m_s)),
                cor=float(m.metric),
                u=float(_known(m.u)),
                ball_id=str(r.ball),
                ball_hit=int(_known(r.ball_hit)),
                shot=s.index,
                temp_c=r.temperature_c,
                rh_pct=r.humidity_pct,
            )
        )
    return found


@dataclass(frozen=True)
class WithinFit:
    """COR against the ball's hit count and the inbound speed, within balls (each ball its own level)."""

    slope: float | None  # COR per hit (the wear), None if not identified
    slope_u: float | None
    speed_slope: float | None  # COR per m/s of inbound speed at the impact point, None if not fitted
    speed_slope_u: float | None
    residual: float  # the within-ball variance left


def within_ball_fit(hits: Sequence[CcorPoint]) -> WithinFit:
    """The common wear slope of COR per hit, with the hit's own speed as a second regressor.

    Least squares on the deviations from each ball's means. The cannon's shot-to-shot speed
    scatter moves COR too (a ball's COR falls with speed); a slope fitted on the hit count alone
    takes a share of that scatter for wear. The speed enters when it varies within the balls.
    """
    by_ball: dict[str, list[CcorPoint]] = defaultdict(list)
    for h in hits:
        by_ball[h.ball_id].append(h)
    rows: list[tuple[float, float, float]] = []
    for balls in by_ball.values():
        n_bar = statistics.fmean(h.ball_hit for h in balls)
        v_bar = statistics.fmean(h.speed_m_s for h in balls)
        e_bar = statistics.fmean(h.cor for h in balls)
        rows += [(h.ball_hit - n_bar, h.speed_m_s - v_bar, h.cor - e_bar) for h in balls]
    x = np.array([r[:2] for r in rows], dtype=float).reshape(-1, 2)
    y = np.array([r[2] for r in rows], dtype=float)
    use = [j for j in (0, 1) if float(np.sum(x[:, j] ** 2)) > 0.0]
    dof = len(hits) - len(by_ball) - len(use)
    if 0 not in use or dof < 1:
        return WithinFit(None, None, None, None, _within_variance(by_ball))
    a = x[:, use]
    # scaled columns: hit counts are units, speed deviations tenths of m/s
    scale = np.sqrt(np.sum(a * a, axis=0))
    coef, *_ = np.linalg.lstsq(a / scale, y, rcond=None)
    resid = y - (a / scale) @ coef
    residual = float(resid @ resid) / dof
    cov = residual * np.linalg.pinv((a / scale).T @ (a / scale)) / np.outer(scale, scale)
    beta = coef / scale
    slope, slope_u = float(beta[0]), math.sqrt(max(0.0, float(cov[0, 0])))
    if len(use) == 1:
        return WithinFit(slope, slope_u, None, None, residual)
    return WithinFit(slope, slope_u, float(beta[1]), math.sqrt(max(0.0, float(cov[1, 1]))), residual)


def _within_variance(by_ball: dict[str, list[CcorPoint]]) -> float:
    """Pooled variance of the hits about their ball's mean (0 if every ball has one hit)."""
    ss = sum(sum((h.cor - statistics.fmean(x.cor for x in b)) ** 2 for h in b) for b in by_ball.values())
    dof = sum(len(b) - 1 for b in by_ball.values())
    return ss / dof if dof > 0 else 0.0


def _between_balls_variance(by_ball: dict[str, list[CcorPoint]]) -> float | None:
    """Pooled variance of the balls' means about the mean of their speed (None: no speed has two balls)."""
    groups: dict[float, list[float]] = defaultdict(list)
    for hs in by_ball.values():
        groups[hs[0].target_speed_m_s].append(statistics.fmean(h.cor for h in hs))
    dof = sum(len(g) - 1 for g in groups.values())
    if dof < 1:
        return None
    return sum(sum((x - statistics.fmean(g)) ** 2 for x in g) for g in groups.values()) / dof


def _mean_u(values: Sequence[float], u_sys: float) -> tuple[float, float, float | None]:
    """(mean, u of the mean, sample SD): u^2 = s^2 / n + u_systematic^2."""
    mean = statistics.fmean(values)
    sd = statistics.stdev(values) if len(values) > 1 else None
    return mean, math.sqrt((sd or 0.0) ** 2 / len(values) + u_sys * u_sys), sd


def _mean_air(at_hits: list[float | None], at_checks: list[Any]) -> float | None:
    """The mean air over the hits (read at each shot), else over the run's environment checks."""
    for values in (at_hits, at_checks):
        known = [float(v) for v in values if v is not None]
        if known and len(known) == len(values):
            return statistics.fmean(known)
    return None


def lot_result(p: BallProcedure, lot_id: str, state: RunState, run_id: str = "") -> LotResult:
    """The lot's result from the run's valid hits (ValueError if there are none).

    Each ball counts once: its mean over its hits. COR (CCOR) = mean of the balls' means, u^2 =
    s_balls^2 / n_balls + u_systematic^2 (the gates' positions, drag and air are shared by every
    hit). The ball-to-ball SD removes the within-ball scatter: sqrt(max(0, s_balls^2 - s_w^2 / K)).
    The wear per hit is the common slope of COR against the ball's hit count within each ball, the
    hit's own inbound speed a second regressor (`within_ball_fit`). The lot's temperature and
    humidity are the means over the hits (read at each shot).
    """
    hits = points(state.shots)
    if not hits:
        raise ValueError("no valid hits: nothing to derive the lot's result from")
    u_sys = max(float(s.outcome.u_systematic or 0.0) for s in state.shots if s.valid and s.outcome)
    by_ball: dict[str, list[CcorPoint]] = defaultdict(list)
    for h in hits:
        by_ball[h.ball_id].append(h)
    ball_means = {b: statistics.fmean(h.cor for h in hs) for b, hs in by_ball.items()}
    mean, u, _ = _mean_u(list(ball_means.values()), u_sys)
    fit = within_ball_fit(hits)
    slope, slope_u, within = fit.slope, fit.slope_u, fit.residual
    k_hits = p.hits_per_ball
    spread = _between_balls_variance(by_ball)  # about each speed's mean: ccor's speeds differ
    sd_between = None if spread is None else math.sqrt(max(0.0, spread - within / k_hits))
    per_speed = []
    for speed in p.speeds_m_s:
        at = [h for h in hits if h.target_speed_m_s == speed]
        if not at:
            continue
        means = [statistics.fmean(h.cor for h in by_ball[b]) for b in dict.fromkeys(h.ball_id for h in at)]
        m, u_m, sd = _mean_u(means, u_sys)
        per_speed.append(
            SpeedPoint(
                target_speed_m_s=speed,
                speed_m_s=statistics.fmean(h.speed_m_s for h in at),
                mean=m,
                u=u_m,
                sd=sd,
                n=len(at),
            )
        )
    envs = [c.data for c in state.environment_checks]
    k = p.decision.coverage_k
    return LotResult(
        lot_id=lot_id,
        procedure=p.test,
        quantity="ccor" if p.test == "ccor" else "cor",
        target={"kind": p.target.kind, "diameter_m": p.target.diameter_m},
        speeds_m_s=tuple(p.speeds_m_s),
        mean=mean,
        u=u,
        U=k * u,
        coverage_k=k,
        sd_between_balls=sd_between,
        wear_per_hit=slope,
        wear_per_hit_u=slope_u,
        speed_slope=fit.speed_slope,
        speed_slope_u=fit.speed_slope_u,
        mean_hit=statistics.fmean(h.ball_hit for h in hits),
        n_balls=len(by_ball),
        hits_per_ball=k_hits,
        n_hits=len(hits),
        temp_c=_mean_air([h.temp_c for h in hits], [e.get("temperature_c") for e in envs]),
        rh_pct=_mean_air([h.rh_pct for h in hits], [e.get("humidity_pct") for e in envs]),
        run_id=run_id,
        per_ball=ball_means,
        per_speed=tuple(per_speed),
        points=tuple(hits),
    )


def _known(value: float | None) -> float:
    """A valid hit's recorded figure (a valid ball-test hit has them all: a record without is damaged)."""
    if value is None:
        raise RigError("a valid ball-test hit without its speed, u or hit count: a damaged record")
    return value


def verdict(p: BallProcedure, lot: dict[str, Any], state: RunState) -> RunVerdict:
    """The verdict of a ball test: the lot's result, and whether it meets its specification.

    PASS unless the lot states a nominal value with a tolerance that the measured value, with its U,
    cannot meet (|mean - nominal| > tolerance + U): a ball test measures, it certifies nothing.
    """
    result = lot_result(p, lot["id"], state)
    the_lot = BallLot.model_validate(lot)
    spec = the_lot.specification
    nominal = spec.nominal_ccor if p.test == "ccor" else spec.nominal_cor
    tolerance = spec.cor_tolerance if p.test == "ball-cor" else None
    meets = the_lot.meets(result.quantity, result.mean, result.U)
    return RunVerdict(
        verdict=Verdict.FAIL if meets is False else Verdict.PASS,
        metric=result.quantity,
        limit=None,
        lot=lot["id"],
        meets_specification=meets,
        nominal=nominal,
        tolerance=tolerance,
        lot_result=result.model_dump(mode="json", exclude={"run_id"}),
    )
