"""The collision model as the DOP853 kernel computes it: one source, compiled or interpreted.

Plain functions of floats and float64 arrays over the kernel's fixed state y = (x1, v1, x2, v2, x3, v3)
(ball, barrel, body; for a rigid barrel x2, v2 is the base) and its parameter vector P (m1, k1, c1,
a, b, m2, k2, c2, inv_body, inv_base, rigid; `fast.kernel_params` builds it): the right-hand side in
and out of contact, the Taylor series of the solution in contact, the separation function g and its
rate, the damping rate that bounds the step holding the contact's end, and the closed-form re-contact
bounds. `_dop853` compiles them with numba, inline into its loops; loaded as the interpreted
kernel it runs these same function objects. Nothing here imports numba or builds a Python object
in the arithmetic.

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

_D, _E, _W, _Z, _G, _F, _JL = range(7)  # the rows of `series`' aux: d, d', d^b, d^(1+a-b), g, F, j L_j
MAX_ORDER = 64  # the longest series `series` makes
RECIPROCALS = np.array([0.0] + [1.0 / k for k in range(1, MAX_ORDER + 2)])  # 1/k, read, not divided


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


def series(y: np.ndarray, p: np.ndarray, order: int, S: np.ndarray, aux: np.ndarray) -> bool:
    """In contact: the Taylor coefficients of the solution through y, to `order` (S[i, k] of state i,
    times t^k); False, with nothing made, where d <= 0 (the force's powers of d branch there).

    From the right-hand side, term by term (automatic differentiation). With d = x1 - x2 > 0 the
    force is F = W G, W = d^b and G = k1 Z + c1 d', Z = d^(1+a-b) (G is the separation function g).
    The powers come from L = log d: d L' = d' gives k L_k = (k d_k - sum_j j L_j d_(k-j)) / d_0, and
    u = exp(q L) gives k u_k = q sum_j j L_j u_(k-j), j = 1..k. aux holds the coefficients of d, d',
    W, Z, G and F in its rows 0-5 and j L_j in row 6 (G to order - 1: its polynomial tells where the
    contact may end within a step). Per order k: four sums of k - 1 terms, run side by side.
    """
    d0 = y[0] - y[2]
    if not d0 > 0.0:
        return False
    k1 = p[1]
    c1 = p[2]
    b = p[4]
    gam = 1.0 + p[3] - b
    inv_m1 = 1.0 / p[0]
    inv_m2 = 1.0 / p[5]
    k2 = p[6]
    c2 = p[7]
    inv_body = p[8]
    inv_base = p[9]
    rigid = p[10] != 0.0
    for i in range(6):
        S[i, 0] = y[i]
    aux[_D, 0] = d0
    aux[_E, 0] = y[1] - y[3]
    w0 = d0**b
    z0 = d0**gam
    g0 = k1 * z0 + c1 * aux[_E, 0]
    aux[_W, 0] = w0
    aux[_Z, 0] = z0
    aux[_G, 0] = g0
    aux[_F, 0] = w0 * g0
    aux[_JL, 0] = 0.0
    inv_d0 = 1.0 / d0
    for k in range(order):
        if k > 0:
            s_l = s_w = s_z = s_f = 0.0  # the odd j
            t_l = t_w = t_z = t_f = 0.0  # the even j: two chains a sum, half the wait
            for j in range(1, k - 1, 2):
                c = aux[_JL, j]
                s_l += c * aux[_D, k - j]
                s_w += c * aux[_W, k - j]
                s_z += c * aux[_Z, k - j]
                s_f += aux[_W, j] * aux[_G, k - j]
                c = aux[_JL, j + 1]
                t_l += c * aux[_D, k - j - 1]
                t_w += c * aux[_W, k - j - 1]
                t_z += c * aux[_Z, k - j - 1]
                t_f += aux[_W, j + 1] * aux[_G, k - j - 1]
            if k % 2 == 0:  # j = k - 1, odd, left over
                c = aux[_JL, k - 1]
                s_l += c * aux[_D, 1]
                s_w += c * aux[_W, 1]
                s_z += c * aux[_Z, 1]
                s_f += aux[_W, k - 1] * aux[_G, 1]
            s_l += t_l
            s_w += t_w
            s_z += t_z
            s_f += t_f
            rk = RECIPROCALS[k]
            jl = (k * aux[_D, k] - s_l) * inv_d0
            aux[_JL, k] = jl
            wk = b * (s_w + jl * w0) * rk
            zk = gam * (s_z + jl * z0) * rk
            gk = k1 * zk + c1 * aux[_E, k]
            aux[_W, k] = wk
            aux[_Z, k] = zk
            aux[_G, k] = gk
            aux[_F, k] = s_f + w0 * gk + wk * g0
        r = RECIPROCALS[k + 1]
        f = aux[_F, k] * r
        S[0, k + 1] = S[1, k] * r
        S[1, k + 1] = -f * inv_m1
        S[2, k + 1] = S[3, k] * r
        if rigid:
            acc = f * inv_base
            S[3, k + 1] = acc
            S[4, k + 1] = S[5, k] * r
            S[5, k + 1] = acc
        else:
            fs = (k2 * (S[2, k] - S[4, k]) + c2 * (S[3, k] - S[5, k])) * r
            S[3, k + 1] = (f - fs) * inv_m2
            S[4, k + 1] = S[5, k] * r
            S[5, k + 1] = fs * inv_body
        aux[_D, k + 1] = S[0, k + 1] - S[2, k + 1]
        aux[_E, k + 1] = S[1, k + 1] - S[3, k + 1]
    return True


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


def g_and_rate(y: np.ndarray, f: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """(gfun(y, p), gdot(y, f, p)), to the last bit, with the one power of |d| they share."""
    d = y[0] - y[2]
    ad = abs(d)
    dd = y[1] - y[3]
    spring = 0.0
    rate = 0.0
    if ad > 0.0:
        q = ad ** (p[3] - p[4])
        spring = p[1] * d * q
        rate = p[1] * (1.0 + p[3] - p[4]) * q * dd
    return spring + p[2] * (y[1] - y[3]), rate + p[2] * (f[1] - f[3])


def g_clear(d_lo: float, d_size: float, v_lo: float, v_size: float, p: np.ndarray) -> bool:
    """True when g > 0 (or NaN: 0 * inf, k1 = 0 at a subnormal d; never <= 0), by a margin far above
    rounding, at every state with d >= d_lo and d' >= v_lo:
    g = k1 d^(1+a-b) + c1 d' rises with both where 1 + a - b >= 0 (k1, c1 >= 0). d_size and v_size:
    the sizes of the numbers d and d' are computed from, whose rounding (~1e-15 of them) the
    margins (a millionth) leave far behind."""
    expo = 1.0 + p[3] - p[4]
    if not (expo >= 0.0 and p[1] >= 0.0 and p[2] >= 0.0 and d_lo > 1e-6 * d_size):
        return False
    spring = p[1] * d_lo**expo
    return spring + p[2] * v_lo > 1e-6 * (spring + p[2] * v_size)


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


def series_damped(aux: np.ndarray, p: np.ndarray) -> bool:
    """`damping_rate` > 0 at the state `series` expanded, from its powers W = |d|^b and
    Z = |d|^(1+a-b) (|d|^a = Z W / |d|): the series step need not take two powers of its own."""
    inv = 1.0 / p[0] + (p[9] if p[10] != 0.0 else 1.0 / p[5])
    lam = p[2] * aux[_W, 0] * inv
    return lam * lam > 4.0 * p[1] * (1.0 + p[3]) * (aux[_Z, 0] * aux[_W, 0] / aux[_D, 0]) * inv


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
