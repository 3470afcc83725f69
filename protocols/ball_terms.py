"""The ball's part of a verdict: what is corrected with a sensitivity the lab measured, what is budgeted.

A certified value is meant for a new ball of the lot's nominal condition (its conditioning
temperature and humidity). The balls the rig fires differ from it in three ways:
- wear: a ball softens with its hits (the lot's ball-cor test measures COR per hit on the plate);
- conditions: a warm, dry ball is livelier (sensitivities per C and per % RH, measured or assumed);
- ball-to-ball spread within the lot (the ball-cor test's standard deviation between balls).
Each is first expressed as a change of the ball's COR on the flat plate, then carried to the metric
by the collision model's ratio g = d(metric)/d(plate COR) for a change of the ball's damping (the
model's own sensitivity, with a relative uncertainty stated here). Sensitivities measured on the
lot correct each hit and budget their own uncertainty; stated or assumed ones correct nothing and
budget the whole effect (the hit's own deviation from the lot's nominal condition).
The lot's spread is never corrected (a ball's own COR is not known): it is budgeted per ball used.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import asdict, dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from rig.core.run_state import ShotEntry
from rig.measure.metrics import compute_metrics
from rig.physics import CollisionParams, PivotedBat, predict_bat, rigid_cor
from rig.protocols.ball_air import fit_air, pooled_wear

PLATE_SPEED_M_S = 26.8  # ASTM F1887: 60 mph onto a rigid flat surface
# [U] relative u of the model's ratio g: the model's barrel (the bat's hoop frequency, the paper's m2
# and c2) against the simulated scenes' own: 2 % (lab, 3600 Hz) and 6 % (softball, 1500 Hz) seen; a
# rigid barrel's g was 25 % off on the softball bat (issue 25)
G_U_REL = 0.15
DAMPING_STEP = 0.01  # relative step of c1 for the ratio
MIN_SPREAD_BALLS = 3  # balls a ball-cor test must have for its ball-to-ball SD to count as measured


class BallTerms(BaseModel):
    """What the lab knows of the balls of a run: recorded whole in RunStarted (`ball`)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    lot: str | None = None
    balls: int | None = None  # the balls in the lot (numbered LOT-01 ...): a run may not use more
    first_ball: int = Field(1, ge=1, description="the run's first ball: the lot's first one never fired")
    source: str = "assumed defaults [U]: no qualified lot named"
    wear_measured: bool = False  # True: wear and spread measured on this lot (ball-cor) -> wear corrected
    conditions_measured: bool = False  # True: the air sensitivities were measured -> corrected
    plate_cor: float | None = None  # the lot's COR on the plate at 60 mph, if measured
    # the lot's latest ball-cor result as it measured it (COR, its standard u, its run): the ball COR
    # a BPF divides by (rig.measure.bpf); None in runs recorded before BPF or without a result
    wall_cor: float | None = None
    wall_cor_u: float | None = Field(None, ge=0.0)
    wall_cor_run: str | None = None
    wall_cor_hit: float | None = None  # the mean hit count behind it (1: a new ball's first hit)
    wall_cor_temp_c: float | None = None  # the lab's mean air over its hits
    wall_cor_rh_pct: float | None = None
    wear_per_hit: float = Field(-0.0003, description="plate COR change per hit of a ball")
    wear_per_hit_u: float = Field(0.0003, ge=0.0)
    sd_between_balls: float = Field(0.003, ge=0.0, description="plate COR SD between the lot's balls")
    cor_per_c: float = Field(0.0015, description="plate COR change per C above the nominal")
    cor_per_c_u: float = Field(0.0015, ge=0.0)
    cor_per_pct_rh: float = Field(-0.0006, description="plate COR change per % RH above the nominal")
    cor_per_pct_rh_u: float = Field(0.0006, ge=0.0)
    air_cov: tuple[float, float, float] | None = None  # measured: var(per C), cov, var(per % RH)
    sensor_u_c: float = Field(0.2, ge=0.0, description="[U] u of the lab's temperature reading, C")
    sensor_u_pct: float = Field(2.0, ge=0.0, description="[U] u of the lab's humidity reading, % RH")
    temp_c: float = 21.0  # the lot's nominal (conditioning) temperature
    rh_pct: float = 50.0
    law: dict[str, float] | None = None  # the ball law's constants (BALL.json), else the paper's
    law_sha256: str | None = None  # the ball file's sha256 (given by --ball, or the lot's recorded law)
    law_from: str | None = None  # where the law came from: "--ball FILE" or "lot LOT's recorded law"
    results: tuple[str, ...] = ()  # the run ids of the lot's ball-cor results the terms rest on


@dataclass(frozen=True)
class HitBall:
    """One valid hit's ball: which, its hits before this one, the lab's air at the shot."""

    ball: str
    hits: int
    temp_c: float
    rh_pct: float


@dataclass(frozen=True)
class BallAdjustment:
    """Per-hit corrections (added to each hit's metric) and the budget's ball terms (standard u)."""

    g: float
    corrections: tuple[float, ...]
    u_wear: float
    u_conditions: float
    u_spread: float
    u_ratio: float
    balls: tuple[str, ...]

    @property
    def u(self) -> float:
        """The ball's combined standard uncertainty."""
        return math.sqrt(self.u_wear**2 + self.u_conditions**2 + self.u_spread**2 + self.u_ratio**2)

    def as_dict(self) -> dict[str, Any]:
        """For the record."""
        return {**asdict(self), "u": self.u}


def law_params(terms: BallTerms, m_ball: float) -> CollisionParams:
    """The ball law the ratio is computed with: the recorded ball file's, else the paper's with m_ball."""
    values = dict(terms.law or {})
    values.setdefault("m1", m_ball)
    return CollisionParams.build(**{k: v for k, v in values.items() if k in CollisionParams.model_fields})


def ratio(
    params: CollisionParams,
    metric: str,
    speed: float,
    q: float,
    moi: float,
    length_m: float,
    hoop_hz: float | None = None,
) -> float:
    """g = d(metric)/d(plate COR) for a change of the ball's damping c1, on the pivoted bat with the
    barrel of hoop frequency `hoop_hz` (None: rigid). A lively barrel stores part of the impact's
    energy in its hoop mode, so the ball's own loss counts for less: on a 1500 Hz softball barrel g is
    about 0.8, against 1.0 on a rigid one."""

    def both(p: CollisionParams) -> tuple[float, float]:
        e_a = predict_bat(p, speed, hoop_hz, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)).e_a
        m = compute_metrics(speed, e_a * speed, q, moi, p.m1, length_m)
        return m.value(metric), rigid_cor(p, PLATE_SPEED_M_S)

    m0, c0 = both(params)
    m1, c1 = both(params.model_copy(update={"c1": params.c1 * (1.0 + DAMPING_STEP)}))
    return (m1 - m0) / (c1 - c0)


def adjust(terms: BallTerms, hits: list[HitBall], g: float) -> BallAdjustment:
    """Corrections and budget terms for these valid hits, given the model's ratio g."""
    n = len(hits)
    mean_hits = sum(h.hits for h in hits) / n
    d_t = sum(h.temp_c - terms.temp_c for h in hits) / n
    d_rh = sum(h.rh_pct - terms.rh_pct for h in hits) / n
    balls = tuple(dict.fromkeys(h.ball for h in hits))
    wear = [terms.wear_per_hit * h.hits if terms.wear_measured else 0.0 for h in hits]
    air = [
        terms.cor_per_c * (h.temp_c - terms.temp_c) + terms.cor_per_pct_rh * (h.rh_pct - terms.rh_pct)
        if terms.conditions_measured
        else 0.0
        for h in hits
    ]
    corrections = tuple(-g * (w + a) for w, a in zip(wear, air, strict=True))
    if terms.wear_measured:
        u_wear = abs(g) * terms.wear_per_hit_u * mean_hits
    else:  # an assumed size: nothing corrected, the whole effect budgeted
        u_wear = abs(g) * math.hypot(terms.wear_per_hit, terms.wear_per_hit_u) * mean_hits
    if terms.conditions_measured:
        var_t, cov, var_rh = terms.air_cov or (terms.cor_per_c_u**2, 0.0, terms.cor_per_pct_rh_u**2)
        var = var_t * d_t * d_t + 2.0 * cov * d_t * d_rh + var_rh * d_rh * d_rh  # d' Cov d
        # the readings' own error moves every hit's correction alike (21 C, 50 % RH are absolute)
        var += (terms.cor_per_c * terms.sensor_u_c) ** 2 + (terms.cor_per_pct_rh * terms.sensor_u_pct) ** 2
        u_cond = abs(g) * math.sqrt(max(0.0, var))
    else:
        u_cond = abs(g) * math.hypot(
            math.hypot(terms.cor_per_c, terms.cor_per_c_u) * d_t,
            math.hypot(terms.cor_per_pct_rh, terms.cor_per_pct_rh_u) * d_rh,
        )
    shares = [sum(1 for h in hits if h.ball == b) / n for b in balls]  # hits on one ball share its offset
    u_spread = abs(g) * terms.sd_between_balls * math.sqrt(sum(s * s for s in shares))
    u_ratio = G_U_REL * abs(sum(corrections) / n)
    return BallAdjustment(g, corrections, u_wear, u_cond, u_spread, u_ratio, balls)


def hit_balls(hits: list[ShotEntry], environment: dict[str, Any] | None, terms: BallTerms) -> list[HitBall]:
    """Each valid hit's ball, its hits before, and the air at its shot (else at the run's check)."""
    env = environment or {}
    out = []
    for h in hits:
        raw, asked = h.raw, h.requested
        ball = None if raw is None else raw.ball
        number = 1 if raw is None or raw.ball_number is None else raw.ball_number
        temp = None if asked is None else asked.temperature_c
        rh = None if asked is None else asked.humidity_pct
        out.append(
            HitBall(
                ball=str(ball or f"ball-{number:02d}"),
                hits=int(0 if raw is None or raw.ball_hits is None else raw.ball_hits),
                temp_c=float(temp if temp is not None else env.get("temperature_c", terms.temp_c)),
                rh_pct=float(rh if rh is not None else env.get("humidity_pct", terms.rh_pct)),
            )
        )
    return out


def terms_from_lot(lot: Any, results: list[Any], law: dict[str, float] | None = None) -> BallTerms:
    """The ball terms of a registered lot (rig.core.ball.BallLot) from its ball-cor results.

    Wear and spread are measured by any one ball-cor test (pooled over the lot's tests); the air's
    sensitivities only by tests at different conditions (rig.protocols.ball_air), else they stay the
    assumed defaults, budgeted whole.
    """
    cor = [r for r in results if r.procedure == "ball-cor" and r.wear_per_hit is not None]
    cond = lot.conditioning
    base: dict[str, Any] = {
        "lot": lot.id,
        "temp_c": cond.temperature_c if cond.temperature_c is not None else 21.0,
        "rh_pct": cond.humidity_pct if cond.humidity_pct is not None else 50.0,
        "law": law,
    }
    defaults = BallTerms()
    wear = pooled_wear(cor)
    if not cor or wear is None:
        return BallTerms(**base, source=f"lot {lot.id}: no ball-cor result; assumed defaults [U]")
    runs = ", ".join(r.run_id[:8] for r in cor)
    base["results"] = tuple(r.run_id for r in cor)  # so that `rig verify` can derive the terms again
    # a spread from fewer than MIN_SPREAD_BALLS balls is not called measured: the default stays
    spreads = [
        r.sd_between_balls for r in cor if r.sd_between_balls is not None and r.n_balls >= MIN_SPREAD_BALLS
    ]
    spread_from = "spread" if spreads else f"spread assumed [U]: fewer than {MIN_SPREAD_BALLS} balls tested"
    values: dict[str, Any] = {
        "wear_measured": True,
        "plate_cor": cor[-1].mean,
        "wall_cor": cor[-1].mean,
        "wall_cor_u": cor[-1].u,
        "wall_cor_run": cor[-1].run_id,
        "wall_cor_hit": cor[-1].mean_hit,
        "wall_cor_temp_c": cor[-1].temp_c,
        "wall_cor_rh_pct": cor[-1].rh_pct,
        "wear_per_hit": wear[0],
        "wear_per_hit_u": wear[1],
        "sd_between_balls": (
            math.sqrt(statistics.fmean(s * s for s in spreads)) if spreads else defaults.sd_between_balls
        ),
    }
    air = fit_air(
        cor,
        base["temp_c"],
        base["rh_pct"],
        math.hypot(defaults.cor_per_c, defaults.cor_per_c_u),
        math.hypot(defaults.cor_per_pct_rh, defaults.cor_per_pct_rh_u),
        wear[0],
    )
    if air is None:
        source = f"lot {lot.id}: ball-cor {runs} (wear, {spread_from}); air sensitivities assumed [U]"
        return BallTerms(**base, **values, source=source)
    var_t, _, var_rh = air.covariance
    source = (
        f"lot {lot.id}: ball-cor {runs} (wear, {spread_from}; air from {air.n_results} tests spanning "
        f"{air.span_c:.1f} C, {air.span_pct:.0f} % RH)"
    )
    values["plate_cor"] = air.cor_nominal  # the lot's COR at its nominal air
    return BallTerms(
        **base,
        **values,
        source=source,
        conditions_measured=True,
        cor_per_c=air.cor_per_c,
        cor_per_c_u=math.sqrt(var_t),
        cor_per_pct_rh=air.cor_per_pct_rh,
        cor_per_pct_rh_u=math.sqrt(var_rh),
        air_cov=air.covariance,
    )
