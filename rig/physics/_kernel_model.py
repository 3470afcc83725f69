"""The collision model as the DOP853 kernel computes it: one source, compiled or interpreted.

Plain functions of floats and float64 arrays over the kernel's fixed state y = (x1, v1, x2, v2, x3, v3)
(ball, barrel, body; for a rigid barrel x2, v2 is the base) and its parameter vector P (m1, k1, c1,
a, b, m2, k2, c2, inv_body, inv_base, rigid; `fast.kernel_params` builds it): the right-hand side in
and out of contact, the separation function g and its rate, the damping rate that bounds the step
holding the contact's end, and the closed-form re-contact bounds. `_dop853` compiles them with
numba, inline into its loops; loaded as the interpreted kernel it runs these same function objects.
Nothing here imports numba or builds a Python object in the arithmetic.

`equations` states the model a second time, on purpose: in the scipy style (named constants,
reduced states, energy terms) for the reference solves, the yardstick the kernel is tested against;
were it to call these functions, a slip in them would be invisible to that test.
tests/physics/test_kernel_model.py holds the two to the same numbers over random states.

numba caches the compiled kernel by the text of `_dop853.py` alone, and does not see a change here:
`_dop853.MODEL_DIGEST` pins this file's text, so an edit here must change that line too (the
kernel refuses to load until it does), and that renews the cache.
"""

from __future__ import annotations

import math

import numpy as np


def rhs(y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """In contact: out = dy/dt under the contact force F = k1 d|d|^a + c1 d'|d|^b (Eqs. 1-2)."""
    d = y[0] - y[2]
    dd = y[1] - y[3]
    ad = abs(d)
    f = p[1] * d * ad ** p[3] + p[2] * dd * ad ** p[4]
    out[0] = y[1]
    out[1] = -f / p[0]
    out[2] = y[3]
    if p[10] != 0.0:
        acc = f * p[9]
        out[3] = acc
        out[4] = y[5]
        out[5] = acc
    else:
        fs = p[6] * (y[2] - y[4]) + p[7] * (y[3] - y[5])
        out[3] = (f - fs) / p[5]
        out[4] = y[5]
        out[5] = fs * p[8]


def rhs_free(y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """Out of contact: ball in free flight, barrel (and body) ringing on their own."""
    out[0] = y[1]
    out[1] = 0.0
    out[2] = y[3]
    fs = p[6] * (y[2] - y[4]) + p[7] * (y[3] - y[5])
    out[3] = -fs / p[5]
    out[4] = y[5]
    out[5] = fs * p[8]


def gfun(y: np.ndarray, p: np.ndarray) -> float:
    """Separation function g = F/|d|^b = k1 d|d|^(a-b) + c1 d': contact ends where it falls through 0."""
    d = y[0] - y[2]
    ad = abs(d)
    spring = 0.0
    if ad > 0.0:
        spring = p[1] * d * ad ** (p[3] - p[4])
    return spring + p[2] * (y[1] - y[3])


def gdot(y: np.ndarray, f: np.ndarray, p: np.ndarray) -> float:
    """Time derivative of g along the solution (f = the state's derivative)."""
    d = y[0] - y[2]
    ad = abs(d)
    dd = y[1] - y[3]
    spring = 0.0
    if ad > 0.0:
        spring = p[1] * (1.0 + p[3] - p[4]) * ad ** (p[3] - p[4]) * dd
    return spring + p[2] * (f[1] - f[3])


def damping_rate(y: np.ndarray, p: np.ndarray) -> float:
    """Decay rate of the relative motion under the ball's damping, c1 |d|^b / (reduced mass), where it
    exceeds twice the contact's own rate (0 elsewhere).

    With b = 0 it is c1 (1/m1 + 1/m2), ~1e5 /s for the paper's ball and barrel: longer steps are
    stable and accurate at their ends, but the 7th-order dense output between the ends is not,
    and the contact's end is located on it. So the step that holds the end is kept to h lam <= kappa,
    kappa = (8! rtol)^(1/8), which bounds the interpolant's error ~ (h lam)^8 / 8! by rtol.
    """
    inv = 1.0 / p[0] + (p[9] if p[10] != 0.0 else 1.0 / p[5])
    ad = abs(y[0] - y[2])
    lam = p[2] * ad ** p[4] * inv
    # only where that decay dominates the contact's own oscillation (rate^2 = k1 (1+a) d^a inv):
    # with the paper's b = 0.52 it does not (rate / omega ~ 0.8 at contact's end) and the step's
    # own error control suffices; with b = 0 it does (~10-30 times)
    if lam * lam <= 4.0 * p[1] * (1.0 + p[3]) * ad ** p[3] * inv:
        return 0.0
    return lam


def g_cannot_rise(d0: float, recede: float, amplitude: float, share: float, mu: float, p: np.ndarray) -> bool:
    """True when, out of contact, g = k1 d|d|^(a-b) + c1 d' can never rise above zero while d > 0.

    The barrel rings about its centre of mass with an amplitude that never grows (energy), so its
    speed and acceleration relative to that centre are at most share w A and share (k2 + c2 w) A / mu
    (w = sqrt(k2/mu)). The ball recedes from the centre at `recede`; if it is faster than the barrel's
    largest speed by `margin`, d' <= -margin for ever, so contact needs k1 d^(1+a-b) > c1 margin,
    i.e. d > d_crit, and d only falls. While d > d_crit, g' = k1 (1+a-b) d^(a-b) d' - c1 a2
    <= -k1 (1+a-b) q margin + c1 a2max, q the least d^(a-b) there; if that is negative g only falls
    where it could be positive, and it starts from 0 at the separation: no new contact. A cheap
    closed-form proof (no integration) that settles the ordinary single-contact impact.
    """
    k1 = p[1]
    c1 = p[2]
    expo = 1.0 + p[3] - p[4]
    if c1 <= 0.0 or expo <= 0.0:
        return False
    k2 = p[6]
    w = math.sqrt(k2 / mu)
    margin = recede - share * w * amplitude
    if margin <= 0.0:
        return False
    if d0 <= 0.0:
        return True
    d_crit = (c1 * margin / k1) ** (1.0 / expo)
    if d0 <= d_crit:
        return True
    q = d_crit ** (expo - 1.0) if expo >= 1.0 else d0 ** (expo - 1.0)
    a2max = share * (k2 + p[7] * w) * amplitude / mu
    return k1 * expo * q * margin > c1 * a2max


def force_escape_time(x1: float, v1: float, reach: float, p: np.ndarray) -> float:
    """Clamped barrel: time after which no contact can begin, from the ball's position and speed and
    the barrel's reach; inf when this bound says nothing.

    The barrel's speed never exceeds w reach (w = sqrt(k2/m2), energy bound) and d <= x1 + reach, so
    g <= k1 (x1 + reach)^(1+a-b) - c1 (-v1 - w reach) while the ball recedes faster than that speed;
    the first term only falls as the ball leaves: once it is below the second, g stays < 0.
    """
    if p[2] <= 0.0 or 1.0 + p[3] - p[4] <= 0.0:
        return math.inf
    margin = -v1 - math.sqrt(p[6] / p[5]) * reach
    if margin <= 0.0:
        return math.inf
    x_safe = (p[2] * margin / p[1]) ** (1.0 / (1.0 + p[3] - p[4])) - reach
    return max(0.0, (x1 - x_safe) / -v1)
