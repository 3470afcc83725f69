"""Bats with a second hoop mode: a population the one-mode model cannot describe.

Part of the population (`share`) has a barrel with two hoop modes: a lumped chain, the ball on
mass m_a, m_a on spring k_a to m_b, m_b on spring k_b (and dampers c_a, c_b) to the bat body of
effective mass I/Q^2 - m_a - m_b, its two modes (body clamped) at the bat's hoop frequency and
`ratio` times it. The rest of the bats have the one-mode barrel. Each bat's e_A is solved here
with scipy's solve_ivp (not the compiled kernel) from the ball's own contact law, the ball leaving
when the contact force falls through zero; BBCOR follows from e_A (rig.measure.metrics). A
calibration of the one-mode model on such a population leaves two groups of residuals.
"""

from __future__ import annotations

import math

import numpy as np

from rig.core.bat import Barrel
from rig.core.units import INCH
from rig.measure.metrics import compute_metrics
from rig.physics import DEFAULT_PARAMS, CollisionParams
from rig.population.dataset import PopulationBat

SPEED_M_S = 60.8
BALL = DEFAULT_PARAMS.model_copy(update={"m1": 0.145})
ONE_MODE = {"m2": 0.24, "c2": 300.0}


def chain_springs(m_a: float, m_b: float, f1: float, f2: float) -> tuple[float, float]:
    """k_a, k_b of the chain (body clamped) whose modes lie at f1 and f2 Hz."""
    w1, w2 = (2 * math.pi * f1) ** 2, (2 * math.pi * f2) ** 2
    s, p = w1 + w2, w1 * w2 * m_a * m_b
    # k_a (1/m_a + 1/m_b) + k_b / m_b = s and k_a k_b = p: a quadratic in k_a (its larger root)
    c = 1 / m_a + 1 / m_b
    disc = s * s - 4 * c * p / m_b
    k_a = (s + math.sqrt(max(disc, 0.0))) / (2 * c)
    return k_a, p / k_a


def e_a_chain(
    ball: CollisionParams, body: float, masses: list[float], springs: list[float], damp: list[float]
) -> float:
    """e_A of the ball on a chain of masses (the first struck) ending on a free body, by solve_ivp."""
    from scipy.integrate import solve_ivp

    m1, k1, c1, a, b = ball.m1, ball.k1, ball.c1, ball.a, ball.b
    ms = [*masses, body]
    n = len(ms)

    def rhs(t: float, y: np.ndarray) -> list[float]:
        x, v = y[: n + 1], y[n + 1 :]
        d, dd = x[0] - x[1], v[0] - v[1]
        ad = abs(d)
        f = k1 * d * ad**a + c1 * dd * ad**b
        acc = [-f / m1]
        for i in range(n):
            force = f if i == 0 else 0.0
            if i > 0:  # spring and damper to the mass before
                force += springs[i - 1] * (x[i] - x[i + 1]) + damp[i - 1] * (v[i] - v[i + 1])
            if i < n - 1:  # ... and to the next
                force -= springs[i] * (x[i + 1] - x[i + 2]) + damp[i] * (v[i + 1] - v[i + 2])
            acc.append(force / ms[i])
        return [*v, *acc]

    def release(t: float, y: np.ndarray) -> float:  # contact force / |d|^b falls through zero
        d, dd = y[0] - y[1], y[n + 1] - y[n + 2]
        return (k1 * d * abs(d) ** (a - b) if d else 0.0) + c1 * dd if t > 1e-7 else 1.0

    release.terminal = True  # type: ignore[attr-defined]
    release.direction = -1  # type: ignore[attr-defined]
    y0 = np.zeros(2 * (n + 1))
    y0[n + 1] = SPEED_M_S
    sol = solve_ivp(rhs, (0.0, 0.01), y0, method="LSODA", rtol=1e-10, atol=1e-12, events=release)
    return -float(sol.y[n + 1, -1]) / SPEED_M_S


def two_mode_population(
    n: int = 60,
    seed: int = 3,
    share: float = 0.5,
    ratio: float = 1.3,
    split: float = 0.5,
    noise: float = 0.003,
) -> list[PopulationBat]:
    """n bats (31-34 in, hoop 1400-3000 Hz), `share` of them with a second hoop mode at `ratio` x."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        length = float(rng.choice([31.0, 32.0, 33.0, 34.0]))
        moi = 0.19 + 0.012 * (length - 33.0) + float(rng.normal(0.0, 0.008))
        hoop = float(rng.uniform(1400.0, 3000.0))
        loc = 6.5
        q = (length - loc) * INCH - 6.0 * INCH
        eff = moi / q**2
        m2 = ONE_MODE["m2"]
        if rng.random() < share:
            masses = [m2 * split, m2 * (1 - split)]
            springs = list(chain_springs(masses[0], masses[1], hoop, ratio * hoop))
            damp = [ONE_MODE["c2"], ONE_MODE["c2"]]
            kind = "two hoop modes"
        else:
            masses, springs, damp = [m2], [m2 * (2 * math.pi * hoop) ** 2], [ONE_MODE["c2"]]
            kind = "one hoop mode"
        e_a = e_a_chain(BALL, eff - sum(masses), masses, springs, damp)
        m = compute_metrics(SPEED_M_S, e_a * SPEED_M_S, q, moi, BALL.m1, length * INCH)
        out.append(
            PopulationBat(
                bat_id=f"TM{i:03d}",
                barrel=Barrel.COMPOSITE,
                hoop_hz=round(hoop, 1),
                length_in=length,
                moi_kgm2=moi,
                location_in=loc,
                bbcor=m.bbcor + float(rng.normal(0.0, noise)),
                source=f"simulated ({kind}; studies.population.twomode)",
            )
        )
    return out
