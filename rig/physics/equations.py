"""Equations of motion of the collision model as pure functions (the scipy style).

Bodies, all moving along the ball's line of flight (positive towards the bat):
- ball, mass m1, position x1, inbound speed v0 at t = 0;
- barrel hoop mode, mass m2, position x2, on a spring k2 and damper c2 to its base;
- base: clamped (the paper's model) or the rigid bat body on the pivot, effective mass I/Q^2.

A rigid barrel (f_hoop -> infinity) is its own model: the barrel moves with its base.

This is the reference formulation, kept apart from the kernel's (`_kernel_model`) on purpose: the
scipy reference solves built on it are the yardstick the kernel is tested against, which they
could not be if both ran one source. tests/physics/test_kernel_model.py holds the two to the same
numbers over random constants and states (right-hand sides, g, damping rate, re-contact bounds).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rig.core.errors import ParameterError
from rig.physics.params import CollisionParams, check_hoop, check_speed


@dataclass(frozen=True)
class Impact:
    """One collision to solve: model constants, inbound speed, hoop frequency, base."""

    params: CollisionParams
    speed: float
    hoop_hz: float | None = None  # None: rigid barrel
    body_mass: float | None = None  # None: clamped base; else the bat body's effective mass, kg

    def __post_init__(self) -> None:
        object.__setattr__(self, "speed", check_speed(self.speed))
        if self.hoop_hz is not None:
            object.__setattr__(self, "hoop_hz", check_hoop(self.hoop_hz))
        if self.body_mass is not None:
            ok = (
                isinstance(self.body_mass, int | float)
                and math.isfinite(self.body_mass)
                and self.body_mass > 0
            )
            if not ok:
                raise ParameterError("body_mass", self.body_mass, "must be a finite number > 0 kg")

    @property
    def rigid(self) -> bool:
        """True for the rigid-barrel model."""
        return self.hoop_hz is None

    @property
    def k2(self) -> float:
        """Barrel spring constant (infinite for the rigid barrel)."""
        return math.inf if self.hoop_hz is None else self.params.k2(self.hoop_hz)

    @property
    def n_states(self) -> int:
        """Number of mechanical states of the reduced system."""
        bodies = 1 + (0 if self.rigid else 1) + (0 if self.body_mass is None else 1)
        return 2 * bodies

    def scales(self) -> np.ndarray:
        """Per-state magnitudes (compression scale for positions, v0 for speeds)."""
        length = self.params.compression_scale(self.speed)
        return np.tile([length, self.speed], self.n_states // 2)

    def time_scale(self) -> float:
        """Characteristic contact time: compression scale over inbound speed."""
        return self.params.compression_scale(self.speed) / self.speed


def contact_force(d: float, dd: float, p: CollisionParams) -> float:
    """Contact force F = k1 d|d|^a + c1 d'|d|^b of the ball on the barrel (Eqs. 1-2)."""
    ad = abs(d)
    return p.k1 * d * ad**p.a + p.c1 * dd * ad**p.b


def separation_function(d: float, dd: float, p: CollisionParams) -> float:
    """g = F/|d|^b = k1 d|d|^(a-b) + c1 d': same sign as F for d > 0, smooth, c1 v0 at t = 0.

    Contact ends where g falls through zero (the ball cannot pull on the barrel). Using F itself
    would give an event at t = 0, where F = 0.
    """
    ad = abs(d)
    spring = 0.0 if ad == 0.0 else p.k1 * d * ad ** (p.a - p.b)
    return spring + p.c1 * dd


def make_rhs(
    imp: Impact, energy: bool = False, free: bool = False
) -> Callable[[float, np.ndarray], list[float]]:
    """Right-hand side for solve_ivp over the reduced states of `imp`.

    States: ball (x1, v1), then barrel (x2, v2) unless rigid, then body (x3, v3) if free. With
    `energy`, two quadratures follow: work dissipated in the ball and in the barrel damper. With
    `free`, the ball is out of contact: no contact force (ball in free flight, barrel ringing).
    """
    p = imp.params
    m1, k1, c1, a, b, m2, c2 = p.m1, p.k1, p.c1, p.a, p.b, p.m2, p.c2
    if free:
        k1 = c1 = 0.0
    k2 = imp.k2
    body = imp.body_mass
    if imp.rigid:
        inv_base = 0.0 if body is None else 1.0 / (m2 + body)

        def rhs_rigid(t: float, y: np.ndarray) -> list[float]:
            s = y.tolist()
            x1, v1 = s[0], s[1]
            x2, v2 = (s[2], s[3]) if body is not None else (0.0, 0.0)
            d, dd = x1 - x2, v1 - v2
            ad = abs(d)
            fd = c1 * dd * ad**b
            f = k1 * d * ad**a + fd
            out = [v1, -f / m1]
            if body is not None:
                out += [v2, f * inv_base]
            if energy:
                out += [fd * dd, 0.0]
            return out

        return rhs_rigid

    inv_body = 0.0 if body is None else 1.0 / body

    def rhs_barrel(t: float, y: np.ndarray) -> list[float]:
        s = y.tolist()
        x1, v1, x2, v2 = s[0], s[1], s[2], s[3]
        x3, v3 = (s[4], s[5]) if body is not None else (0.0, 0.0)
        d, dd = x1 - x2, v1 - v2
        ad = abs(d)
        fd = c1 * dd * ad**b
        f = k1 * d * ad**a + fd
        rv = v2 - v3
        fs = k2 * (x2 - x3) + c2 * rv
        out = [v1, -f / m1, v2, (f - fs) / m2]
        if body is not None:
            out += [v3, fs * inv_body]
        if energy:
            out += [fd * dd, c2 * rv * rv]
        return out

    return rhs_barrel


def initial_state(imp: Impact, energy: bool = False) -> np.ndarray:
    """Ball at the barrel surface moving at v0; everything else at rest."""
    y0 = np.zeros(imp.n_states + (2 if energy else 0))
    y0[1] = imp.speed
    return y0


def relative_motion(imp: Impact, y: np.ndarray) -> tuple[float, float]:
    """Compression d = x1 - x2 and its rate from a state vector."""
    if imp.rigid and imp.body_mass is None:
        return float(y[0]), float(y[1])
    return float(y[0] - y[2]), float(y[1] - y[3])


def mechanical_energy(imp: Impact, y: np.ndarray) -> dict[str, float]:
    """Kinetic and stored energies of a state, J (the ball's stored energy is k1 |d|^(2+a)/(2+a))."""
    p = imp.params
    d, _ = relative_motion(imp, y)
    out = {
        "ball_kinetic": 0.5 * p.m1 * float(y[1]) ** 2,
        "ball_stored": p.k1 * abs(d) ** (2.0 + p.a) / (2.0 + p.a),
        "barrel_kinetic": 0.0,
        "barrel_stored": 0.0,
        "body_kinetic": 0.0,
    }
    if imp.rigid:
        if imp.body_mass is not None:
            out["body_kinetic"] = 0.5 * (p.m2 + imp.body_mass) * float(y[3]) ** 2
        return out
    x3, v3 = (float(y[4]), float(y[5])) if imp.body_mass is not None else (0.0, 0.0)
    out["barrel_kinetic"] = 0.5 * p.m2 * float(y[3]) ** 2
    out["barrel_stored"] = 0.5 * imp.k2 * (float(y[2]) - x3) ** 2
    if imp.body_mass is not None:
        out["body_kinetic"] = 0.5 * imp.body_mass * v3**2
    return out


def contact_scale(imp: Impact) -> float:
    """Magnitude of the separation function g in contact: k1 L^(1+a-b) + c1 v0, L the compression scale."""
    p = imp.params
    length = p.compression_scale(imp.speed)
    return p.k1 * length ** (1.0 + p.a - p.b) + p.c1 * imp.speed


def contact_indicator(imp: Impact, y: np.ndarray) -> float:
    """> 0 exactly when the ball presses on the barrel (d > 0 and F > 0): min(d G/L, g).

    Continuous where g is; it rises through zero where a new contact begins, whether the ball
    meets the barrel's surface again (d through 0) or F turns positive while d > 0.
    """
    d, dd = relative_motion(imp, y)
    length = imp.params.compression_scale(imp.speed)
    return min(d * contact_scale(imp) / length, separation_function(d, dd, imp.params))


def escape_time(imp: Impact, y: np.ndarray) -> float:
    """After a separation: time after which the ball can never touch the barrel again (0: never
    again from now on; inf: a new contact is certain or cannot be excluded this way).

    Out of contact the barrel (with the body, if free) is a damped linear system whose centre of
    mass moves at a constant speed V and whose energy of vibration E never grows; so the barrel's
    surface stays within reach = (share of the relative motion) * sqrt(2 E / k2) of that centre.
    The ball moves at a constant v1. If v1 <= V, the ball's lead over the centre of mass never
    grows, so once x1 - X <= -reach we have d = x1 - x2 <= 0 for ever: no contact (contact needs
    d > 0). That happens at the latest after (x1 - X + reach) / (V - v1). A rigid barrel has
    reach 0 and d' = v1 - V constant, so g = k1 d|d|^(a-b) + c1 d' falls for ever once d' <= 0.
    """
    p = imp.params
    s = [float(v) for v in y[: imp.n_states]]
    x1, v1 = s[0], s[1]
    if imp.rigid:
        v_base = 0.0 if imp.body_mass is None else s[3]
        return 0.0 if v1 <= v_base else math.inf
    x2, v2 = s[2], s[3]
    k2 = imp.k2
    if imp.body_mass is None:
        centre, speed_c, share = 0.0, 0.0, 1.0
        r, vr, mu = x2, v2, p.m2
    else:
        x3, v3 = s[4], s[5]
        mass = p.m2 + imp.body_mass
        centre = (p.m2 * x2 + imp.body_mass * x3) / mass
        speed_c = (p.m2 * v2 + imp.body_mass * v3) / mass
        share = imp.body_mass / mass
        r, vr, mu = x2 - x3, v2 - v3, p.m2 * imp.body_mass / mass
    amplitude = math.sqrt(r * r + mu * vr * vr / k2)
    reach = share * amplitude
    lead = x1 - centre + reach
    if lead <= 0.0 and v1 <= speed_c:
        return 0.0
    if v1 >= speed_c:
        return math.inf
    if g_cannot_rise(imp, x1 - x2, speed_c - v1, amplitude, share, mu):
        return 0.0
    wait = lead / (speed_c - v1)
    if imp.body_mass is None:
        wait = min(wait, _force_escape_time(imp, x1, v1, reach))
    return wait


def g_cannot_rise(imp: Impact, d0: float, recede: float, amplitude: float, share: float, mu: float) -> bool:
    """Out of contact, g = k1 d|d|^(a-b) + c1 d' can never rise above zero while d > 0 (proof below).

    The barrel rings about its centre of mass with an amplitude A that never grows, so its speed
    and acceleration relative to that centre are at most share w A and share (k2 + c2 w) A / mu
    (w = sqrt(k2/mu)). If the ball recedes from the centre faster than the barrel's largest speed,
    by `margin`, then d' <= -margin for ever: contact needs k1 d^(1+a-b) > c1 margin (d > d_crit)
    and d only falls. Where d > d_crit, g' = k1 (1+a-b) d^(a-b) d' - c1 a2 <= -k1 (1+a-b) q margin
    + c1 a2max (q the least d^(a-b) there); if that is negative, g only falls wherever it could be
    positive, and it starts from zero at the separation. The kernel's `_kernel_model.g_cannot_rise`,
    stated again here on purpose (see the module's docstring).
    """
    p = imp.params
    expo = 1.0 + p.a - p.b
    if p.c1 <= 0.0 or expo <= 0.0:
        return False
    k2 = imp.k2
    w = math.sqrt(k2 / mu)
    margin = recede - share * w * amplitude
    if margin <= 0.0:
        return False
    if d0 <= 0.0:
        return True
    d_crit = (p.c1 * margin / p.k1) ** (1.0 / expo)
    if d0 <= d_crit:
        return True
    q = d_crit ** (expo - 1.0) if expo >= 1.0 else d0 ** (expo - 1.0)
    a2max = share * (k2 + p.c2 * w) * amplitude / mu
    return p.k1 * expo * q * margin > p.c1 * a2max


def _force_escape_time(imp: Impact, x1: float, v1: float, reach: float) -> float:
    """Clamped barrel: when g = k1 d|d|^(a-b) + c1 (v1 - v2) must stay < 0 for ever.

    The barrel's speed never exceeds w reach (w = sqrt(k2/m2), energy bound) and d <= x1 + reach.
    If the ball recedes faster (v1 + w reach < 0), g <= k1 (x1 + reach)^(1+a-b) - c1 (-v1 - w reach),
    whose first term only falls as the ball leaves: once it is below the second, no contact can
    begin. inf when this bound says nothing. The kernel's `_kernel_model.force_escape_time`, stated again.
    """
    p = imp.params
    margin = -v1 - math.sqrt(imp.k2 / p.m2) * reach
    if margin <= 0.0 or p.c1 == 0.0 or 1.0 + p.a - p.b <= 0.0:
        return math.inf
    x_safe = (p.c1 * margin / p.k1) ** (1.0 / (1.0 + p.a - p.b)) - reach
    return max(0.0, (x1 - x_safe) / -v1)


def damping_rate(imp: Impact, y: np.ndarray) -> float:
    """Decay rate of the relative motion under the ball's damping, c1 |d|^b / (reduced mass), 1/s,
    where it exceeds twice the contact's own rate sqrt(k1 (1+a) |d|^a / reduced mass); else 0."""
    p = imp.params
    d, _ = relative_motion(imp, y)
    if imp.rigid:
        inv = 1.0 / p.m1 + (0.0 if imp.body_mass is None else 1.0 / (p.m2 + imp.body_mass))
    else:
        inv = 1.0 / p.m1 + 1.0 / p.m2
    lam = p.c1 * abs(d) ** p.b * inv
    if lam * lam <= 4.0 * p.k1 * (1.0 + p.a) * abs(d) ** p.a * inv:
        return 0.0
    return lam


def creep_rates(imp: Impact) -> tuple[float, float] | None:
    """Clamped flexible barrel with c2^2 > 4 k2 m2 (over-damped): the decay rates (slow, fast) of its
    free motion, 1/s, the roots of m2 s^2 - c2 s + k2 = 0; None for any other barrel."""
    if imp.rigid or imp.body_mass is not None:
        return None
    p, k2 = imp.params, imp.k2
    disc = p.c2 * p.c2 - 4.0 * k2 * p.m2
    if not disc > 0.0:
        return None
    root = p.c2 + math.sqrt(disc)
    return 2.0 * k2 / root, root / (2.0 * p.m2)  # the slow one without cancellation


CREEP_INTERVALS = 64  # first partition of the window in `cannot_touch`
CREEP_SPLIT = 8  # parts an undecided interval is cut into
CREEP_MAX_OPEN = 4096  # undecided intervals beyond which `cannot_touch` gives up (False)


def cannot_touch(imp: Impact, y: np.ndarray, window: float, rel: float, abs_x: float, abs_v: float) -> bool:
    """Free flight from state y of a clamped over-damped barrel (`creep_rates`): True when the ball
    provably cannot press on the barrel within `window` s, even were the barrel's position and speed
    off the exact ones by up to rel * (their largest size) + abs_x and + abs_v (a solver's error).

    Out of contact the motion is known in closed form: the ball moves at its constant v1, and the
    barrel x2(t) = A exp(-s t) + B exp(-f t) with its rates s < f (A + B = x2, -s A - f B = v2). On an
    interval [t_a, t_b] every one of these terms is monotone, so its largest and least values are
    at the ends: upper bounds on d = x1 - x2 and d' = v1 - v2 over the interval follow from the two
    end values of each term. Contact (the indicator > 0) needs d > 0 and g = k1 d|d|^(a-b) + c1 d' > 0,
    and g never falls as d or d' grow (1 + a - b >= 0, c1 >= 0); so an interval where the raised
    bounds give d < 0 or g < 0 holds no contact. Undecided intervals are split into CREEP_SPLIT parts
    until all are decided (True) or more than CREEP_MAX_OPEN remain open (False: no proof).
    """
    rates = creep_rates(imp)
    p = imp.params
    expo = 1.0 + p.a - p.b
    if rates is None or not (window > 0.0 and math.isfinite(window)) or expo < 0.0 or p.c1 < 0.0:
        return False
    slow, fast = rates
    x1, v1, x2, v2 = (float(v) for v in y[:4])
    a_slow = (fast * x2 + v2) / (fast - slow)
    b_fast = x2 - a_slow
    err_x = rel * (abs(a_slow) + abs(b_fast)) + abs_x
    err_v = rel * (slow * abs(a_slow) + fast * abs(b_fast)) + abs_v
    lo = np.linspace(0.0, window, CREEP_INTERVALS + 1)
    hi = lo[1:]
    lo = lo[:-1]
    while lo.size:
        es_lo, es_hi = a_slow * np.exp(-slow * lo), a_slow * np.exp(-slow * hi)
        ef_lo, ef_hi = b_fast * np.exp(-fast * lo), b_fast * np.exp(-fast * hi)
        x2_least = np.minimum(es_lo, es_hi) + np.minimum(ef_lo, ef_hi) - err_x
        d_most = x1 + np.maximum(v1 * lo, v1 * hi) - x2_least
        v2_least = -slow * np.maximum(es_lo, es_hi) - fast * np.maximum(ef_lo, ef_hi) - err_v
        dd_most = v1 - v2_least
        d_pos = np.maximum(d_most, 0.0)
        g_most = p.k1 * d_pos**expo + p.c1 * dd_most
        open_ = ~((d_most < 0.0) | (g_most < 0.0))
        if not open_.any():
            return True
        if np.count_nonzero(open_) * CREEP_SPLIT > CREEP_MAX_OPEN:
            return False
        lo, hi = lo[open_], hi[open_]
        cuts = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, CREEP_SPLIT + 1)
        lo, hi = cuts[:, :-1].ravel(), cuts[:, 1:].ravel()
        if np.any(hi <= lo):
            return False  # split down to the floats' resolution without a decision
    return True
