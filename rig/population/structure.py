"""Is what the fit leaves noise? Residual structure that says the model family does not describe the bats.

A one-mode model fitted to bats it cannot describe (a second hoop mode in part of the population,
two constructions) leaves residuals with structure rather than scatter; fitting on regardless
gives a calibration whose scatter is the misfit, and such data once kept the fit running for
more than 25 minutes. Two checks on the residuals of the family's best in-sample fit:

- a trend with hoop frequency: least squares of the residuals on Legendre polynomials of degree
  1-3 in the scaled hoop frequency; structure when the trend explains at least TREND_SHARE of
  their variance and the F test gives p < TREND_P;
- two modes: a two-component normal mixture with one variance (EM); structure when the means
  lie at least MODE_SEPARATION standard deviations apart (Ashman's D; two equal normals are
  bimodal from 2), each component holds at least MODE_SHARE of the bats and twice the log
  likelihood gained over one normal is at least MODE_LR (on normal residuals its 99th percentile
  is about 9 at 20-4000 bats), and the residuals themselves dip between the two means: within half
  a component SD of the valley between them lie at most MODE_DIP times as many as within half an
  SD of the emptier mean, or fewer by MODE_DIP_Z standard errors of the two counts (many bats tell
  a shallow dip from a flat top: a second review saw a 15 % group 4 SD out missed more often at
  4,000 bats than at 40). Without the dip a flat-topped spread passes the other three (a uniform
  one fits two normals 3.5 SD apart: an outside review saw one-construction populations whose
  contact stiffness varied by +-35 % refused as "two constructions").
Either refuses the calibration with the structure seen. Fewer than MIN_BATS bats are not checked.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rig.population.calibrate import CalibrationRefused

MIN_BATS = 20
TREND_SHARE = 0.25
TREND_P = 1e-4
MODE_SEPARATION = 3.0
MODE_SHARE = 0.1
MODE_LR = 16.0
MODE_DIP = 0.5
MODE_DIP_Z = 2.0
EM_TOL = 1e-10  # EM stops once a step gains less log-likelihood than this (at most `steps` steps)


class ModelFamilyRefused(CalibrationRefused):
    """The residuals have structure the model family cannot take up; the message says which."""


def hoop_trend(hoops: Sequence[float], residuals: Sequence[float]) -> tuple[float, float, float]:
    """(share of the residual variance a cubic in hoop frequency explains, F-test p, trend span)."""
    from scipy.special import betainc  # on first use (the fit has imported scipy.optimize)

    f = np.asarray(hoops, dtype=float)
    r = np.asarray(residuals, dtype=float)
    x = (2.0 * f - f.min() - f.max()) / max(f.max() - f.min(), 1e-9)
    basis = np.polynomial.legendre.legvander(x, 3)
    coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
    trend = basis @ coef
    total = float(np.sum((r - r.mean()) ** 2))
    left = float(np.sum((r - trend) ** 2))
    if total <= 0.0:
        return 0.0, 1.0, 0.0
    share = 1.0 - left / total
    q, dof = 3, len(r) - 4
    if left <= 0.0:
        return share, 0.0, float(np.ptp(trend))
    fstat = (share / q) / ((1.0 - share) / dof)
    p = float(betainc(0.5 * dof, 0.5 * q, dof / (dof + q * fstat)))
    return share, p, float(np.ptp(trend))


def dip(residuals: Sequence[float], means: tuple[float, float], sd: float) -> tuple[float, float]:
    """Residuals within sd/2 of the valley between the two means (where two normals of this sd,
    weighted by the shares on either side of the midpoint, are least dense) over those within sd/2
    of the emptier mean (at least 1): well below 1 where two groups leave a gap, about 1 over a
    flat top; and how many standard errors of the two counts the valley lies below that mean's."""
    r = np.asarray(residuals, dtype=float)
    low, high = means
    w = float(np.mean(r <= 0.5 * (low + high)))
    grid = np.linspace(low, high, 101)[1:-1]
    density = w * np.exp(-0.5 * ((grid - low) / sd) ** 2) + (1.0 - w) * np.exp(
        -0.5 * ((grid - high) / sd) ** 2
    )
    valley = float(grid[int(np.argmin(density))])
    near = [int(np.sum(np.abs(r - c) <= 0.5 * sd)) for c in (low, high, valley)]
    peak, between = min(near[0], near[1]), near[2]
    z = (peak - between) / np.sqrt(peak + between) if peak + between else 0.0
    return between / max(1, peak), float(z)


def two_modes(
    residuals: Sequence[float], steps: int = 300
) -> tuple[float, float, float, tuple[float, float]]:
    """(Ashman's D, smaller weight, 2 x log-likelihood gain over one normal, the two means) of a
    two-component equal-variance normal mixture fitted by EM (the best of three starts, each until a
    step gains less than EM_TOL in log-likelihood)."""
    r = np.asarray(residuals, dtype=float)
    n = len(r)
    m, s = float(r.mean()), float(r.std())
    if s == 0.0:
        return 0.0, 0.0, 0.0, (m, m)
    z = (r - m) / s
    one = -0.5 * n * (np.log(2.0 * np.pi) + 1.0)
    best = (0.0, 0.0, -np.inf, (m, m))
    for split in np.quantile(z, [0.25, 0.5, 0.75]):
        below = z <= split
        if below.all() or not below.any():
            continue
        mu = np.array([z[below].mean(), z[~below].mean()])
        pi = np.array([below.mean(), 1.0 - below.mean()])
        var, ll = 0.5, -np.inf
        for _ in range(steps):
            d = -0.5 * (z[:, None] - mu[None, :]) ** 2 / var + np.log(pi)[None, :]
            top = d.max(axis=1, keepdims=True)
            w = np.exp(d - top)
            tot = w.sum(axis=1, keepdims=True)
            last, ll = ll, float(np.sum(top[:, 0] + np.log(tot[:, 0])) - 0.5 * n * np.log(2.0 * np.pi * var))
            if ll - last < EM_TOL:
                break  # EM never lowers the likelihood: this start has converged
            w /= tot
            nk = w.sum(axis=0)
            if np.any(nk < 1e-9):
                break
            pi, mu = nk / n, (w * z[:, None]).sum(axis=0) / nk
            var = max(float((w * (z[:, None] - mu[None, :]) ** 2).sum() / n), 1e-6)
        gain = 2.0 * (ll - one)
        if gain > best[2]:
            sep = float(abs(mu[1] - mu[0]) / np.sqrt(var))
            best = (sep, float(pi.min()), gain, (m + s * float(mu.min()), m + s * float(mu.max())))
    return best


def check_structure(hoops: Sequence[float], residuals: Sequence[float], variant: str) -> None:
    """ModelFamilyRefused naming the structure when the residuals are not scatter (see the module)."""
    if len(residuals) < MIN_BATS:
        return
    seen = []
    share, p, span = hoop_trend(hoops, residuals)
    if share >= TREND_SHARE and p < TREND_P:
        seen.append(
            f"a trend with hoop frequency explains {100 * share:.0f} % of the residual variance"
            f" (cubic, F test p = {p:.1g}, {span:.4f} from end to end)"
        )
    sep, weight, gain, means = two_modes(residuals)
    if sep >= MODE_SEPARATION and weight >= MODE_SHARE and gain >= MODE_LR:
        gap, z = dip(residuals, means, abs(means[1] - means[0]) / sep)
        if gap <= MODE_DIP or z >= MODE_DIP_Z:
            seen.append(
                f"the residuals are bimodal (two groups at {means[0]:+.4f} and {means[1]:+.4f},"
                f" {sep:.1f} standard deviations apart, the smaller {100 * weight:.0f} % of the bats;"
                f" between them {gap:.2f} times as many as at the emptier group)"
            )
    if seen:
        raise ModelFamilyRefused(
            f"the model family does not describe this population: after its best fit ({variant}) "
            + "; ".join(seen)
            + ". A one-mode model cannot take that up (a second hoop mode, two constructions?):"
            " calibrate each kind of bat apart"
        )
