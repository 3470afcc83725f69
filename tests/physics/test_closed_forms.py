"""The solvers (the DOP853 kernel, its series path, the scipy reference) against solutions derived by
hand, and against the published rigid-barrel anchors.

The closed forms are derived here from the equations of motion, never taken from the code:
1. a linear Kelvin-Voigt ball (a = b = 0) on a rigid wall, a damped oscillator whose contact ends
   where F = k d + c d' returns to zero (not where d does);
2. an undamped power-law ball (c1 = 0) on a rigid wall: COR = 1 and a contact time in Gamma functions;
3. a linear undamped ball on a clamped flexible barrel: a two-mass modal solution, energy conserved.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.linalg import eigh
from scipy.optimize import brentq
from scipy.special import gamma

from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams
from rig.physics.reference import CollisionResult, solve_reference

Solver = Callable[[Impact, float], CollisionResult]

SOLVERS: dict[str, Solver] = {
    "fast": lambda imp, rtol: fast.solve(imp, rtol),
    "series": lambda imp, rtol: fast.solve_series(imp, rtol),  # the curve's path: Taylor series steps
    "reference": lambda imp, rtol: solve_reference(imp, "DOP853", rtol),
}
TIGHT = 1e-12  # solver tolerance for the closed-form comparisons
CLOSE = 1e-8  # required agreement (COR absolute, contact time relative)


@pytest.fixture(params=sorted(SOLVERS))
def solver(request: pytest.FixtureRequest) -> Solver:
    """Each solver in turn."""
    return SOLVERS[request.param]


# --- 1. linear Kelvin-Voigt ball on a rigid wall -------------------------------------------------


def kelvin_voigt(m: float, k: float, c: float, v0: float) -> tuple[float, float, float]:
    """(COR, contact time, compression at separation) of m d'' + c d' + k d = 0, d(0) = 0, d'(0) = v0.

    Contact ends at the first t > 0 where F = k d + c d' = -m d'' vanishes.
    """
    w0 = math.sqrt(k / m)
    s = c / (2.0 * m)  # decay rate sigma = zeta w0
    if s < w0:  # under-damped: d = (v0/wd) e^(-s t) sin(wd t)
        wd = math.sqrt(w0 * w0 - s * s)
        # F/(v0 e^(-s t)) = ((k - c s)/wd) sin(wd t) + c cos(wd t) = R sin(wd t + psi)
        psi = math.atan2(c, (k - c * s) / wd)
        T = (math.pi - psi) / wd
        decay = math.exp(-s * T)
        v_end = v0 * decay * (math.cos(wd * T) - s / wd * math.sin(wd * T))
        d_end = v0 / wd * decay * math.sin(wd * T)
    else:  # over-damped: d = v0 (e^(r1 t) - e^(r2 t)) / (r1 - r2); F = 0 where d'' = 0
        q = math.sqrt(s * s - w0 * w0)
        r1, r2 = -s + q, -s - q
        T = 2.0 * math.log(r2 / r1) / (r1 - r2)
        v_end = v0 * (r1 * math.exp(r1 * T) - r2 * math.exp(r2 * T)) / (r1 - r2)
        d_end = v0 * (math.exp(r1 * T) - math.exp(r2 * T)) / (r1 - r2)
    return -v_end / v0, T, d_end


# (k1, c1, speed) spanning light damping, the paper's c1 on a stiff spring, and over-damping
KV_CASES = [
    (1e6, 100.0, 1.0),  # zeta 0.13
    (1e5, 10.0, 0.01),  # zeta 0.04
    (1e6, 1000.0, 5.0),  # zeta 1.3, over-damped
    (6e6, 5000.0, 60.8),  # zeta 2.7, over-damped
    (4e7, 1500.0, 100.0),  # zeta 0.3
]


@pytest.mark.parametrize(("k1", "c1", "speed"), KV_CASES)
def test_kelvin_voigt_ball_on_rigid_wall(solver: Solver, k1: float, c1: float, speed: float) -> None:
    """COR, contact time and residual compression match the damped-oscillator solution to 1e-8."""
    params = CollisionParams.build(k1=k1, c1=c1, a=0.0, b=0.0)
    cor, T, d_end = kelvin_voigt(params.m1, k1, c1, speed)
    res = solver(Impact(params, speed), TIGHT)
    assert res.cor == pytest.approx(cor, abs=CLOSE)
    assert res.contact_time_s == pytest.approx(T, rel=CLOSE)
    # contact ends at F = 0 with the ball still compressed, not at d = 0
    assert d_end > 0.0
    assert res.final_state[0] == pytest.approx(d_end, rel=1e-6)


def test_kelvin_voigt_cor_is_independent_of_speed(solver: Solver) -> None:
    """A linear ball has one COR at every speed (the equations scale with v0)."""
    params = CollisionParams.build(k1=1e6, c1=300.0, a=0.0, b=0.0)
    cors = [solver(Impact(params, v), TIGHT).cor for v in (0.01, 1.0, 100.0)]
    assert max(cors) - min(cors) < CLOSE
    assert cors[0] == pytest.approx(kelvin_voigt(params.m1, 1e6, 300.0, 1.0)[0], abs=CLOSE)


# --- 2. undamped power-law ball on a rigid wall --------------------------------------------------


def power_law_contact_time(m: float, k: float, a: float, v0: float) -> float:
    """T = 2 (d_max/v0) sqrt(pi) Gamma(1 + 1/n) / Gamma(1/2 + 1/n), n = 2 + a (energy integral)."""
    n = 2.0 + a
    d_max = (n * m * v0 * v0 / (2.0 * k)) ** (1.0 / n)
    return 2.0 * d_max / v0 * math.sqrt(math.pi) * gamma(1.0 + 1.0 / n) / gamma(0.5 + 1.0 / n)


@pytest.mark.parametrize("a", [0.0, 0.25, 0.5, 0.6495, 1.0])
@pytest.mark.parametrize("speed", [0.01, 1.0, 60.8, 100.0])
def test_undamped_power_law_ball_on_rigid_wall(solver: Solver, a: float, speed: float) -> None:
    """c1 = 0: the ball rebounds at its inbound speed after the Gamma-function contact time."""
    params = CollisionParams.build(c1=0.0, a=a)
    res = solver(Impact(params, speed), TIGHT)
    assert res.cor == pytest.approx(1.0, abs=CLOSE)
    assert res.contact_time_s == pytest.approx(
        power_law_contact_time(params.m1, params.k1, a, speed), rel=CLOSE
    )


@pytest.mark.parametrize(("a", "b"), [(0.0, 1.0), (1.0, 0.0), (0.5, 0.5)])
def test_undamped_contact_end_does_not_depend_on_b(solver: Solver, a: float, b: float) -> None:
    """With c1 = 0, b only shapes the event function g = k1 d|d|^(a-b); the contact must not change.

    a = 0, b = 1 makes g a step (k1 sign d); a = 1, b = 0 makes it cross zero with zero slope.
    """
    params = CollisionParams.build(c1=0.0, a=a, b=b)
    res = solver(Impact(params, 26.8), TIGHT)
    assert res.cor == pytest.approx(1.0, abs=CLOSE)
    assert res.contact_time_s == pytest.approx(
        power_law_contact_time(params.m1, params.k1, a, 26.8), rel=CLOSE
    )


# --- 3. linear undamped two-mass system (clamped flexible barrel) --------------------------------


def two_mass_modal(m1: float, k1: float, m2: float, k2: float, v0: float) -> tuple[float, np.ndarray, int]:
    """Every contact of the linear two-mass system, piece by piece in closed form:
    (time of the last separation, [x1, v1, x2, v2] there, number of contacts).

    In contact: M x'' + K x = 0 with K = [[k1, -k1], [-k1, k1 + k2]], solved by its normal modes;
    with c1 = 0 and a = 0 the force k1 d vanishes with d, so a contact ends where d = x1 - x2
    falls through zero. Out of contact the ball flies at constant speed and the barrel rings at
    sqrt(k2/m2); a new contact begins where d rises through zero. The ball has left for good once
    it recedes (v1 < 0) beyond the barrel's amplitude sqrt(x2^2 + v2^2 m2/k2).
    """
    M = np.diag([m1, m2])
    K = np.array([[k1, -k1], [-k1, k1 + k2]])
    w2, phi = eigh(K, M)  # mass-normalised modes: phi.T M phi = I
    w = np.sqrt(w2)
    wb = math.sqrt(k2 / m2)

    def in_contact(x0: np.ndarray, u0: np.ndarray) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
        q0, p0 = phi.T @ M @ x0, phi.T @ M @ u0  # modal displacements and velocities

        def at(t: float) -> tuple[np.ndarray, np.ndarray]:
            q = q0 * np.cos(w * t) + p0 / w * np.sin(w * t)
            p = -q0 * w * np.sin(w * t) + p0 * np.cos(w * t)
            return phi @ q, phi @ p

        return at

    def in_flight(x0: np.ndarray, u0: np.ndarray) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
        def at(t: float) -> tuple[np.ndarray, np.ndarray]:
            c, s_ = math.cos(wb * t), math.sin(wb * t)
            x = np.array([x0[0] + u0[0] * t, x0[1] * c + u0[1] / wb * s_])
            u = np.array([u0[0], -x0[1] * wb * s_ + u0[1] * c])
            return x, u

        return at

    def next_zero(motion: Callable, sign: float, t_stop: float) -> float | None:
        """First time d = x1 - x2 crosses zero into sign * d > 0 (None before t_stop)."""

        def gap(t: float) -> float:
            x, _ = motion(t)
            return float(x[0] - x[1])

        h = 2.0 * math.pi / max(float(w.max()), wb) / 400.0
        t = h
        while t < t_stop:
            if sign * gap(t) > 0.0:
                if sign * gap(t - h) > 0.0:  # only at t - h = 0, where d = 0 to rounding
                    return 0.0
                return brentq(gap, t - h, t, xtol=1e-18, rtol=4.0 * np.finfo(float).eps)
            t += h
        return None

    t_now, x, u, contacts = 0.0, np.array([0.0, 0.0]), np.array([v0, 0.0]), 0
    while True:
        contacts += 1
        motion = in_contact(x, u)
        dt = next_zero(motion, -1.0, 1e3)
        assert dt is not None
        x, u = motion(dt)
        t_sep = t_now + dt
        reach = math.sqrt(x[1] ** 2 + u[1] ** 2 * m2 / k2)
        horizon = (x[0] + reach) / -u[0] if u[0] < 0.0 else 1.0
        flight = in_flight(x, u)
        dt = next_zero(flight, 1.0, horizon)
        if dt is None:
            return t_sep, np.array([x[0], u[0], x[1], u[1]]), contacts
        x, u = flight(dt)
        t_now = t_sep + dt


# (k1, m2, hoop_hz): near-rigid, paper-like, heavy soft and light stiff barrels
TWO_MASS_CASES = [
    (1e6, 0.09, 1250.0),
    (6e7, 0.09, 1250.0),
    (1e6, 1.0, 300.0),
    (1e6, 0.01, 5000.0),
    (1e5, 10.0, 100.0),
    (1e7, 0.5, 2000.0),
]


@pytest.mark.parametrize(("k1", "m2", "hoop"), TWO_MASS_CASES)
def test_linear_two_mass_matches_modal_solution(solver: Solver, k1: float, m2: float, hoop: float) -> None:
    """COR, contact time and the barrel's final state match the normal-mode solution."""
    params = CollisionParams.build(k1=k1, m2=m2, a=0.0, b=0.0, c1=0.0, c2=0.0)
    v0 = 3.0
    k2 = m2 * (2.0 * math.pi * hoop) ** 2
    T, state, contacts = two_mass_modal(params.m1, k1, m2, k2, v0)
    res = solver(Impact(params, v0, hoop), TIGHT)
    assert res.contacts == contacts
    assert res.cor == pytest.approx(-state[1] / v0, abs=CLOSE)
    assert res.contact_time_s == pytest.approx(T, rel=CLOSE)
    assert res.final_state[3] == pytest.approx(state[3], abs=CLOSE * v0)  # barrel velocity
    assert res.final_state[2] == pytest.approx(state[2], abs=1e-6 * abs(state[0]))  # barrel position


@pytest.mark.parametrize(("k1", "m2", "hoop"), TWO_MASS_CASES)
def test_linear_two_mass_conserves_energy(solver: Solver, k1: float, m2: float, hoop: float) -> None:
    """KE in = ball KE out + barrel kinetic + barrel spring energy (the ball is unloaded at d = 0)."""
    params = CollisionParams.build(k1=k1, m2=m2, a=0.0, b=0.0, c1=0.0, c2=0.0)
    v0 = 3.0
    k2 = m2 * (2.0 * math.pi * hoop) ** 2
    res = solver(Impact(params, v0, hoop), TIGHT)
    x1, v1, x2, v2 = res.final_state[:4]
    e_in = 0.5 * params.m1 * v0**2
    e_out = 0.5 * params.m1 * v1**2 + 0.5 * m2 * v2**2 + 0.5 * k2 * x2**2 + 0.5 * k1 * (x1 - x2) ** 2
    assert e_out == pytest.approx(e_in, rel=1e-9)


# --- published anchors ---------------------------------------------------------------------------

# rigid-barrel COR of the paper's ball (numerics.md, section 6), quoted to 3 decimals
RIGID_ANCHORS = [
    (0.01, 0.798),
    (0.1, 0.733),
    (1.0, 0.653),
    (5.0, 0.590),
    (26.8, 0.519),
    (60.8, 0.484),
    (100.0, 0.462),
]


@pytest.mark.parametrize(("speed", "cor"), RIGID_ANCHORS)
def test_rigid_cor_matches_published_anchor(
    solver: Solver, paper_params: CollisionParams, speed: float, cor: float
) -> None:
    """Rigid-barrel COR at the paper's constants, to the anchors' 1e-3."""
    assert solver(Impact(paper_params, speed), 1e-10).cor == pytest.approx(cor, abs=1e-3)


@pytest.mark.parametrize(("speed", "contact_ms"), [(60.8, 0.580), (26.8, 0.717)])
def test_rigid_contact_time_matches_published_anchor(
    solver: Solver, paper_params: CollisionParams, speed: float, contact_ms: float
) -> None:
    """Rigid contact times quoted in numerics.md section 1.1 (0.580 ms and 0.717 ms)."""
    assert solver(Impact(paper_params, speed), 1e-10).contact_time_s * 1e3 == pytest.approx(
        contact_ms, abs=1e-3
    )
