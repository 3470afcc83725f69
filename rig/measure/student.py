"""Student-t distribution for whole degrees of freedom, in pure Python (no scipy.stats: ~1 s to import).

The two-sided probability A(t | nu) = P(|T| <= t) is a finite sum for whole nu (Abramowitz and
Stegun 26.7.3-4, theta = atan(t / sqrt(nu))):
  nu odd:  A = (2/pi) (theta + s (c + 2/3 c^3 + ... + [2.4...(nu-3)] / [1.3...(nu-2)] c^(nu-2)))
  nu even: A = s (1 + 1/2 c^2 + 1.3/2.4 c^4 + ... + [1.3...(nu-3)] / [2.4...(nu-2)] c^(nu-2))
with s = sin(theta), c = cos(theta).
Every term is positive (no cancellation). The quantile inverts A by safeguarded Newton steps
(A is increasing and concave in t > 0) from the normal quantile, which lies below it.
"""

from __future__ import annotations

import math
from statistics import NormalDist

MAX_STEPS = 200
REL_TOL = 1e-13


def _check_dof(dof: int) -> None:
    if isinstance(dof, bool) or not isinstance(dof, int) or dof < 1:
        raise ValueError(f"degrees of freedom must be a whole number >= 1, not {dof!r}")


def two_sided(t: float, dof: int) -> float:
    """P(|T| <= t) for Student's t with `dof` degrees of freedom (t >= 0)."""
    _check_dof(dof)
    if t <= 0.0:
        return 0.0
    if math.isinf(t):
        return 1.0
    theta = math.atan2(t, math.sqrt(dof))
    s, c = math.sin(theta), math.cos(theta)
    c2 = c * c
    if dof % 2:
        term, total = c, c if dof > 1 else 0.0
        for k in range(3, dof - 1, 2):  # the (k-1)/k factors: 2/3, 4/5, ...
            term *= c2 * (k - 1) / k
            total += term
        return min(1.0, 2.0 / math.pi * (theta + s * total))
    term, total = 1.0, 1.0
    for k in range(2, dof - 1, 2):  # the (k-1)/k factors: 1/2, 3/4, ...
        term *= c2 * (k - 1) / k
        total += term
    return min(1.0, s * total)


def cdf(t: float, dof: int) -> float:
    """P(T <= t)."""
    half = 0.5 * two_sided(abs(t), dof)
    return 0.5 + half if t >= 0.0 else 0.5 - half


def pdf(t: float, dof: int) -> float:
    """The density of Student's t at t."""
    _check_dof(dof)
    nu = float(dof)
    log_norm = math.lgamma(0.5 * (nu + 1.0)) - math.lgamma(0.5 * nu) - 0.5 * math.log(nu * math.pi)
    return math.exp(log_norm - 0.5 * (nu + 1.0) * math.log1p(t * t / nu))


def quantile(p: float, dof: int) -> float:
    """The t with P(T <= t) = p (0 < p < 1): scipy.stats.t.ppf(p, dof) without importing scipy.stats."""
    _check_dof(dof)
    if not 0.0 < p < 1.0:
        raise ValueError(f"probability {p!r} must lie between 0 and 1")
    if p == 0.5:
        return 0.0
    if p < 0.5:
        return -quantile(1.0 - p, dof)
    if dof == 1:  # Cauchy: closed form (Newton crawls up its heavy tail)
        return math.tan(math.pi * (p - 0.5))
    if dof == 2:
        return (2.0 * p - 1.0) / math.sqrt(2.0 * p * (1.0 - p))
    target = 2.0 * p - 1.0
    lo, hi = NormalDist().inv_cdf(p), math.inf  # the normal quantile lies below the t quantile
    t = lo
    for _ in range(MAX_STEPS):
        g = two_sided(t, dof) - target
        if g < 0.0:
            lo = t
        else:
            hi = t
        step = g / (2.0 * pdf(t, dof))
        nxt = t - step
        if not lo < nxt < hi:  # keep to the bracket: bisect (or double while no upper end is known)
            nxt = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * lo
        if abs(nxt - t) <= REL_TOL * abs(nxt):
            return nxt
        t = nxt
    return t
