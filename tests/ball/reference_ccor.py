"""A reference solver of the founding paper's Eq. 1 against a rigid wall (x2 = 0), written for the
tests only: scipy's solve_ivp (DOP853, tight tolerances) with its own contact-end event, sharing no
code with rig.physics. It makes the CCOR data that rig's ball fit is checked against.

m1 x'' = -k1 x|x|^a - c1 x'|x|^b with x the ball's compression, x(0) = 0, x'(0) = v0. Contact ends
when the force k1 x^(1+a) + c1 x' x^b falls to zero; the event divides it by x^b (smooth, positive
at t = 0, where the force itself is zero). CCOR = -x'(t_end) / v0.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

PAPER = {"m1": 0.145, "k1": 60e6, "c1": 5000.0, "a": 0.6495, "b": 0.5202}


def reference_ccor(
    speed: float, m1: float, k1: float, c1: float, a: float, b: float, rtol: float = 1e-11
) -> float:
    """The ball's COR on a rigid immovable wall at inbound speed `speed` (m/s)."""

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        x, v = float(y[0]), float(y[1])
        ax = abs(x)
        return [v, -(k1 * x * ax**a + c1 * v * ax**b) / m1]

    def contact_end(_t: float, y: np.ndarray) -> float:
        x, v = float(y[0]), float(y[1])
        return k1 * x * abs(x) ** (a - b) + c1 * v

    contact_end.terminal = True  # type: ignore[attr-defined]
    contact_end.direction = -1  # type: ignore[attr-defined]
    # an upper bound of the contact time: a quarter period of the undamped ball, many times over
    depth = ((2.0 + a) * m1 * speed**2 / (2.0 * k1)) ** (1.0 / (2.0 + a))
    t_end = 50.0 * depth / speed
    sol = solve_ivp(
        rhs,
        (0.0, t_end),
        [0.0, speed],
        method="DOP853",
        rtol=rtol,
        atol=[1e-3 * depth * rtol, 1e-3 * speed * rtol],
        events=contact_end,
        first_step=1e-6 * depth / speed,
    )
    t_events, y_events = sol.t_events, sol.y_events  # both set: an event was given
    if sol.status != 1 or t_events is None or y_events is None or not t_events[0].size:
        raise RuntimeError(f"contact did not end at {speed} m/s: {sol.message}")
    v_out = float(y_events[0][0][1])
    cor = -v_out / speed
    assert math.isfinite(cor) and 0.0 < cor < 1.0
    return cor
