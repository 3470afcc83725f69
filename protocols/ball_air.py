"""The lot's sensitivity to the lab's air, fitted from its ball-cor results at different conditions.

One ball-cor test lasts minutes: the air hardly moves during it, so one test cannot tell how the
ball's COR follows temperature and humidity. A lab that tests the lot at several conditions (hours
of the day, days, or in a conditioning chamber) can: each result's mean COR against its mean air,

    COR_i = c0 + s_T (T_i - T0) + s_RH (RH_i - RH0)

weighted by each result's random u. In a lab whose air swings, temperature and humidity move
together and the data pin only their combination along the swing; a prior of zero with the stated
magnitude (the assumed sensitivities and their u) closes the other direction, so the fitted
covariance is honest in both: a bat test's air on the same line is corrected with a small u, air
off that line with the prior's. c0 is the lot's COR at its nominal conditions. When the residual
scatter exceeds the stated u (Birge ratio above 1, on n minus the effective number of parameters)
the covariance is scaled up by it.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass

import numpy as np

from rig.core.ball import LotResult

MIN_RESULTS = 3  # results at different conditions before the air is called measured
MIN_SPAN_C = 0.5  # their temperatures must span at least this, or their humidities MIN_SPAN_PCT
MIN_SPAN_PCT = 2.0


@dataclass(frozen=True)
class AirFit:
    """The lot's COR at nominal air and its sensitivities to temperature and humidity."""

    cor_nominal: float
    cor_per_c: float
    cor_per_pct_rh: float
    covariance: tuple[float, float, float]  # var(s_T), cov(s_T, s_RH), var(s_RH)
    n_results: int
    span_c: float
    span_pct: float
    birge: float  # sqrt(chi2 / dof) of the fit; 1 is what the stated u predict
    dof: float  # n minus the hat matrix's trace: the prior's share of the slopes is not the data's


def result_u_random(result: LotResult) -> float:
    """A result's random u: the scatter of its balls' means over their number (spread included)."""
    means = list((result.per_ball or {}).values())
    if len(means) < 2:
        return float(result.u)
    return statistics.stdev(means) / math.sqrt(len(means))


def fit_air(
    results: list[LotResult], temp0: float, rh0: float, prior_c: float, prior_pct: float, wear: float = 0.0
) -> AirFit | None:
    """The air fit over ball-cor `results` (LotResult), or None where the air is not identified.

    Each result's mean is first moved to the results' common mean hit count with `wear` (COR per
    hit). `prior_c`, `prior_pct`: the sensitivities' prior standard deviations about zero.
    """
    at = [(r, r.temp_c, r.rh_pct) for r in results if r.temp_c is not None and r.rh_pct is not None]
    if len(at) < MIN_RESULTS:
        return None
    usable = [r for r, _, _ in at]
    temps = [t for _, t, _ in at]
    rhs = [h for _, _, h in at]
    span_c, span_pct = max(temps) - min(temps), max(rhs) - min(rhs)
    if span_c < MIN_SPAN_C and span_pct < MIN_SPAN_PCT:
        return None
    hit_bar = statistics.fmean(float(r.mean_hit) for r in usable)
    y = np.array([float(r.mean) - wear * (float(r.mean_hit) - hit_bar) for r in usable])
    x = np.array([[1.0, t - temp0, h - rh0] for t, h in zip(temps, rhs, strict=True)])
    w = np.array([1.0 / max(result_u_random(r), 1e-9) ** 2 for r in usable])
    prior = np.diag([0.0, 1.0 / prior_c**2, 1.0 / prior_pct**2])
    a = x.T @ (w[:, None] * x) + prior
    cov = np.linalg.inv(a)
    beta = cov @ (x.T @ (w * y))
    resid = y - x @ beta
    # the data's degrees of freedom: n minus the effective number of parameters (the hat matrix's
    # trace: 1 for the intercept plus what the data, not the prior, determine of the slopes)
    dof = len(usable) - float(np.trace(x @ cov @ (x.T * w)))
    birge = math.sqrt(float(resid @ (w * resid)) / dof) if dof > 1e-6 else 1.0
    cov = cov * max(1.0, birge) ** 2
    return AirFit(
        cor_nominal=float(beta[0]),
        cor_per_c=float(beta[1]),
        cor_per_pct_rh=float(beta[2]),
        covariance=(float(cov[1, 1]), float(cov[1, 2]), float(cov[2, 2])),
        n_results=len(usable),
        span_c=span_c,
        span_pct=span_pct,
        birge=birge,
        dof=dof,
    )


def pooled_wear(results: list[LotResult]) -> tuple[float, float] | None:
    """The inverse-variance mean of the results' wear per hit and its u (None if none measured it);
    the u is scaled up by the Birge ratio when the results scatter more than their u say."""
    known = [(r.wear_per_hit, r.wear_per_hit_u or 0.0) for r in results if r.wear_per_hit is not None]
    if not known:
        return None
    if any(u <= 0.0 for _, u in known):
        return statistics.fmean(v for v, _ in known), 0.0
    weights = [1.0 / (u * u) for _, u in known]
    mean = sum(wt * v for wt, (v, _) in zip(weights, known, strict=True)) / sum(weights)
    chi2 = sum(wt * (v - mean) ** 2 for wt, (v, _) in zip(weights, known, strict=True))
    birge = math.sqrt(chi2 / (len(known) - 1)) if len(known) > 1 else 1.0  # runs that disagree: u grows
    return mean, max(1.0, birge) * math.sqrt(1.0 / sum(weights))
