"""A BPF's verdict: the hits' BBCOR moved to the lot's nominal ball, over the lot's COR moved there too.

BPF = BBCOR / ball COR divides a bat test by a ball test, each made with the lot's balls at their own
hit counts and in their own lab air. Both are therefore taken to the lot's nominal ball (a new ball at
its conditioning temperature and humidity) with the lot's terms (rig.protocols.ball_terms):

- BBCOR: each hit corrected (and budgeted) as any certification with --ball-lot, with the model's
  g = dBBCOR/d(plate COR) (rig.protocols.verdict.ball_part);
- the COR: the lot's latest ball-cor result, moved from its mean hit count to a new ball by the wear
  per hit (its u budgeted), and from the test's mean air to the nominal by the air sensitivities (their
  u budgeted);
- the air: both sides moved to the nominal air by the same sensitivities, the lot's measured ones or
  else the assumed ones [U] with their stated u. A BPF divides a bat test by a ball test made at
  another hour: left uncorrected, the two airs leave a bias of s (g d_hits - BPF d_cor) / COR that
  repeats on every run of a bat at its hour of the lab's day (issue 25: +0.005 in BPF on the lab
  scene's sample bat), which budgeting it whole does not remove.

The COR's own u (its test's) then enters the mean BPF once (rig.measure.bpf.bpf_u): one value
divides every hit. The wear per hit and the air sensitivities act on both sides with one value each,
so their u is one term of the BPF (rig.measure.bpf.shared_u), not a hits' term and a COR's term.
"""

from __future__ import annotations

import math
from typing import Any

from rig.core.errors import RigError
from rig.measure.bpf import bpf_u, shared_u
from rig.protocols.ball_terms import BallAdjustment, BallTerms, HitBall, hit_balls
from rig.protocols.state import RunState, ShotEntry


def nominal_cor(state: RunState, correct_air: bool = True) -> dict[str, Any]:
    """The lot's COR on the rigid wall for a new ball at the lot's nominal air, with its u and parts.

    `correct_air`: move it to the nominal air by the assumed sensitivities too when the lot did not
    measure them (as bpf_result moves the hits); False: only by measured ones, else the whole effect
    budgeted (a run whose hits are not moved)."""
    recorded = (state.setup or {}).get("ball") or {}
    if recorded.get("wall_cor") is None or recorded.get("wall_cor_u") is None:
        raise RigError(
            "a BPF run needs its ball COR: the lot's ball-cor result (rig certify --ball-lot LOT), "
            "which this run did not record"
        )
    t = BallTerms.model_validate(recorded)
    cor, u_test = float(t.wall_cor or 0.0), float(t.wall_cor_u or 0.0)
    before = max(0.0, (t.wall_cor_hit or 1.0) - 1.0)  # hits before, on average, in the ball test
    wear, u_wear = -t.wear_per_hit * before, t.wear_per_hit_u * before
    d_t = (t.wall_cor_temp_c if t.wall_cor_temp_c is not None else t.temp_c) - t.temp_c
    d_rh = (t.wall_cor_rh_pct if t.wall_cor_rh_pct is not None else t.rh_pct) - t.rh_pct
    if t.conditions_measured or correct_air:  # measured, or assumed [U] with their stated u
        air = -(t.cor_per_c * d_t + t.cor_per_pct_rh * d_rh)
        var_t, cov, var_rh = t.air_cov or (t.cor_per_c_u**2, 0.0, t.cor_per_pct_rh_u**2)
        u_air = math.sqrt(max(0.0, var_t * d_t * d_t + 2.0 * cov * d_t * d_rh + var_rh * d_rh * d_rh))
    else:  # not moved: the whole effect budgeted
        air = 0.0
        u_air = math.hypot(
            math.hypot(t.cor_per_c, t.cor_per_c_u) * d_t,
            math.hypot(t.cor_per_pct_rh, t.cor_per_pct_rh_u) * d_rh,
        )
    return {
        "measured": cor,
        "u_test": u_test,
        "wear_correction": wear,
        "u_wear": u_wear,
        "air_correction": air,
        "u_air": u_air,
        "nominal": cor + wear + air,
        "u": math.sqrt(u_test**2 + u_wear**2 + u_air**2),
        "run": t.wall_cor_run or "",
        "lot": t.lot or "",
        "hits_before": before,
        "d_air": (d_t, d_rh),
    }


def shared_terms(
    t: BallTerms, balls: list[HitBall], wall: dict[str, Any], g: float, bpf_mean: float
) -> tuple[float, float]:
    """(u_air, u_wear) of the BPF from the sensitivities shared by the hits and the COR (bpf.shared_u).

    Both sides are moved by the sensitivities (measured, or assumed [U]): what is left is their error,
    budgeted with their covariance (assumed: their stated u, per C and per % RH independently), and
    the readings' own u (taken independent between the bat's run and the ball test, which may be on
    other sensors)."""
    n, cor = len(balls), wall["nominal"]
    d_hits = (sum(b.temp_c - t.temp_c for b in balls) / n, sum(b.rh_pct - t.rh_pct for b in balls) / n)
    d_cor = wall["d_air"]
    var_t, cov, var_rh = t.air_cov or (t.cor_per_c_u**2, 0.0, t.cor_per_pct_rh_u**2)
    readings = math.hypot(t.cor_per_c * t.sensor_u_c, t.cor_per_pct_rh * t.sensor_u_pct)
    u_air = math.hypot(
        shared_u(g, bpf_mean, cor, d_hits, d_cor, ((var_t, cov), (cov, var_rh))),
        readings * math.hypot(g, bpf_mean) / cor,
    )
    wear_u = t.wear_per_hit_u if t.wear_measured else math.hypot(t.wear_per_hit, t.wear_per_hit_u)
    mean_hits = sum(b.hits for b in balls) / n
    u_wear = shared_u(g, bpf_mean, cor, (mean_hits,), (wall["hits_before"],), ((wear_u * wear_u,),))
    return u_air, u_wear


def bpf_result(
    p_basis: str,
    bbcor_hits: list[float],
    u_bbcor_hits: float,
    ball: BallAdjustment | None,
    state: RunState,
    hits: list[ShotEntry],
) -> tuple[list[float], dict[str, Any]]:
    """Each hit's BPF (its BBCOR corrected for its ball, over the nominal COR) and the verdict's parts.

    `u_bbcor_hits`: the mean BBCOR's u from the hits (budget and scatter); the ball's terms add to it:
    its spread and ratio to the hits' part, its wear and air as terms shared with the COR."""
    wall = nominal_cor(state, correct_air=ball is not None)
    air = [0.0] * len(bbcor_hits) if ball is None else air_corrections(state, hits, ball.g)
    corrected = (
        list(bbcor_hits)
        if ball is None
        else [b + c + a for b, c, a in zip(bbcor_hits, ball.corrections, air, strict=True)]
    )
    cor = wall["nominal"]
    values = [b / cor for b in corrected]
    mean = sum(values) / len(values)
    u_bbcor = u_bbcor_hits if ball is None else math.hypot(u_bbcor_hits, ball.u)
    shared_air = shared_wear = 0.0
    if ball is None:  # no ratio g to carry the ball's terms: each side's whole u, in quadrature
        parts = bpf_u(mean, u_bbcor, cor, wall["u"])
    else:
        t = BallTerms.model_validate((state.setup or {}).get("ball") or {})
        shared_air, shared_wear = shared_terms(t, hit_balls(hits, state.environment, t), wall, ball.g, mean)
        own = math.sqrt(u_bbcor_hits**2 + ball.u_spread**2 + ball.u_ratio**2)  # the hits' alone
        parts = bpf_u(mean, own, cor, wall["u_test"])
    u = math.sqrt(parts.u**2 + shared_air**2 + shared_wear**2)
    return values, {
        "basis": p_basis,
        "bbcor_mean": mean * cor,
        "u_bbcor": u_bbcor,
        "u_bbcor_hits": u_bbcor_hits,
        "ball_cor": cor,
        "ball_cor_u": wall["u"],
        "ball_cor_measured": wall,
        "ball_cor_run": wall["run"],
        "lot": wall["lot"],
        "u_from_bbcor": parts.from_bbcor,
        "u_from_ball_cor": parts.from_ball_cor,
        "u_shared_air": shared_air,
        "u_shared_wear": shared_wear,
        "u": u,
        "air_corrections": air,
        "correlated": "the ball COR's u enters once, for the mean: one lot value divides every hit",
    }


def air_corrections(state: RunState, hits: list[ShotEntry], g: float) -> list[float]:
    """Each hit's BBCOR moved to the lot's nominal air by the assumed sensitivities [U] (-g s.d), as
    nominal_cor moves the COR; none when the lot measured them (ball_terms.adjust has moved the hits)."""
    t = BallTerms.model_validate((state.setup or {}).get("ball") or {})
    if t.conditions_measured:
        return [0.0] * len(hits)
    return [
        -g * (t.cor_per_c * (b.temp_c - t.temp_c) + t.cor_per_pct_rh * (b.rh_pct - t.rh_pct))
        for b in hit_balls(hits, state.environment, t)
    ]
