"""Reference solves of the collision model with scipy's solve_ivp (any of its methods).

Slow but independent of the fast kernel: used for the work-precision study, for energy
bookkeeping and as the yardstick the fast solver is tested against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import solve_ivp

from rig.core.errors import ParameterError, SolverError
from rig.physics.equations import (
    Impact,
    initial_state,
    make_rhs,
    mechanical_energy,
    relative_motion,
    separation_function,
)
from rig.physics.params import CollisionParams, check_tolerance

SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")


@dataclass(frozen=True)
class CollisionResult:
    """Outcome of one collision: COR = rebound speed / inbound speed of the ball."""

    cor: float
    contact_time_s: float
    ball_exit_velocity: float  # m/s along the line of flight; negative = rebounding
    final_state: tuple[float, ...]
    nfev: int
    method: str
    rtol: float
    energy: dict[str, float] = field(default_factory=dict)


def contact_time_limit(params: CollisionParams, speed: float, hoop_hz: ArrayLike | None) -> Any:
    """A generous bound on the contact time, s (per hoop frequency for an array); contact not over
    by then is an error.

    A barrel much lighter than the ball rides its spring with the ball for ~pi sqrt(m1/k2), which
    is sqrt(m1/m2) barrel periods: the bound grows with that ratio.
    """
    limit = 500.0 * params.compression_scale(speed) / speed
    if hoop_hz is None:
        return limit
    return limit + 20.0 / np.asarray(hoop_hz, dtype=float) * max(1.0, math.sqrt(params.m1 / params.m2))


def _time_limit(imp: Impact) -> float:
    """contact_time_limit of one impact."""
    return float(contact_time_limit(imp.params, imp.speed, imp.hoop_hz))


def _first_step(imp: Impact, first_step: float | str) -> dict[str, float]:
    if first_step == "scipy":
        return {}
    if first_step == "auto":
        return {"first_step": 1e-4 * imp.time_scale()}
    if isinstance(first_step, int | float) and math.isfinite(first_step) and first_step > 0:
        return {"first_step": float(first_step)}
    raise ParameterError("first_step", first_step, "must be 'auto', 'scipy' or a positive number of s")


def solve_reference(
    imp: Impact,
    method: str = "DOP853",
    rtol: float = 1e-10,
    energy: bool = False,
    first_step: float | str = "auto",
) -> CollisionResult:
    """Solve one collision with solve_ivp; contact ends where the contact force returns to zero.

    `first_step` "auto" starts at 1e-4 of the contact's time scale, as the kernel does, because
    scipy's own choice ("scipy") is too long for the non-smooth d^b onset of the contact force;
    a number sets it. A brief dip of the force below zero inside one step is found too: the
    minima of g are events, and contact ends at the first one where g < 0.
    """
    if method not in SCIPY_METHODS:
        raise ParameterError("method", method, f"choose one of {', '.join(SCIPY_METHODS)}")
    rtol = check_tolerance(rtol)
    p = imp.params
    fun = make_rhs(imp, energy=energy)
    y0 = initial_state(imp, energy=energy)
    atol = rtol * imp.scales()
    if energy:
        ke0 = 0.5 * p.m1 * imp.speed**2
        atol = np.concatenate([atol, [rtol * ke0, rtol * ke0]])

    def ended(t: float, y: np.ndarray) -> float:
        d, dd = relative_motion(imp, y)
        return separation_function(d, dd, p)

    ended.terminal = True  # type: ignore[attr-defined]
    ended.direction = -1  # type: ignore[attr-defined]
    moving_barrel = not (imp.rigid and imp.body_mass is None)

    def dip(t: float, y: np.ndarray) -> float:
        d, dd = relative_motion(imp, y)
        acc = fun(t, y)
        ddd = acc[1] - acc[3] if moving_barrel else acc[1]
        spring = p.k1 * (1.0 + p.a - p.b) * abs(d) ** (p.a - p.b) * dd if d != 0.0 else 0.0
        return spring + p.c1 * ddd

    dip.direction = 1  # type: ignore[attr-defined]  # g' from - to +: a minimum of g
    t_max = _time_limit(imp)
    options = _first_step(imp, first_step)
    where = f"speed {imp.speed:g} m/s, hoop {imp.hoop_hz or 'rigid'} Hz, {method} rtol {rtol:g}"

    def run(t_stop: float) -> object:
        try:
            return solve_ivp(
                fun, (0.0, t_stop), y0, method=method, rtol=rtol, atol=atol, events=[ended, dip], **options
            )
        except (RuntimeError, ValueError, ZeroDivisionError) as exc:
            raise SolverError(f"scipy {method} failed ({exc}) at {where}") from None

    sol = run(t_max)
    if sol.status == 1 and len(sol.t_events[0]):
        t_sep = float(sol.t_events[0][0])
        for t_m, y_m in zip(sol.t_events[1], sol.y_events[1], strict=True):
            if 0.0 < t_m < t_sep and separation_function(*relative_motion(imp, y_m), p) < 0.0:
                # F dipped below zero inside one step: contact really ended before t_m
                sol = run(float(t_m))
                break
    if sol.status == -1:
        raise SolverError(f"solver failed ({sol.message}) at {where}")
    if sol.status != 1 or len(sol.t_events[0]) == 0:
        raise SolverError(f"contact did not end within {t_max:.3g} s at {where}")
    t_end = float(sol.t_events[0][0])
    if not t_end > 0.0:
        raise SolverError(f"contact ended at t = {t_end!r} (before it began) at {where}")
    y_end = np.asarray(sol.y_events[0][0], dtype=float)
    if not np.all(np.isfinite(y_end)):
        raise SolverError(f"non-finite state at separation at {where}")
    v_exit = float(y_end[1])
    terms: dict[str, float] = {}
    if energy:
        terms = mechanical_energy(imp, y_end)
        terms["ball_dissipated"] = float(y_end[imp.n_states])
        terms["barrel_dissipated"] = float(y_end[imp.n_states + 1])
        terms["inbound_kinetic"] = 0.5 * p.m1 * imp.speed**2
        out = sum(v for k, v in terms.items() if k != "inbound_kinetic")
        terms["residual"] = terms["inbound_kinetic"] - out
    return CollisionResult(
        cor=-v_exit / imp.speed,
        contact_time_s=t_end,
        ball_exit_velocity=v_exit,
        final_state=tuple(float(v) for v in y_end[: imp.n_states]),
        nfev=int(sol.nfev),
        method=method,
        rtol=rtol,
        energy=terms,
    )


def momentum(imp: Impact, state: tuple[float, ...] | np.ndarray) -> float:
    """Total momentum of the free bodies (meaningful when the base is free), kg m/s."""
    p = imp.params
    y = np.asarray(state, dtype=float)
    if imp.body_mass is None:
        return math.nan
    if imp.rigid:
        return p.m1 * y[1] + (p.m2 + imp.body_mass) * y[3]
    return p.m1 * y[1] + p.m2 * y[3] + imp.body_mass * y[5]
