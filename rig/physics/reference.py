"""Reference solves of the collision model with scipy's solve_ivp (any of its methods).

Slow but independent of the fast kernel: used for the work-precision study, for energy
bookkeeping and as the yardstick the fast solver is tested against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike

from rig.core.errors import ParameterError, SolverError
from rig.physics.equations import (
    Impact,
    cannot_touch,
    contact_indicator,
    creep_rates,
    damping_rate,
    escape_time,
    initial_state,
    make_rhs,
    mechanical_energy,
    relative_motion,
    separation_function,
)
from rig.physics.params import CollisionParams, check_tolerance

SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
ScipyMethod = Literal["RK45", "DOP853", "Radau", "BDF", "LSODA"]  # SCIPY_METHODS, as a type


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
    contacts: int = 1  # separate contacts before the ball left for good


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


def _time_limit(imp: Impact, scale: float | None = None) -> float:
    """contact_time_limit of one impact, in plain floats (the same operations, without numpy's
    per-call cost); `scale`: its compression scale, when already known."""
    params, speed, hoop = imp.params, imp.speed, imp.hoop_hz
    limit = 500.0 * (params.compression_scale(speed) if scale is None else scale) / speed
    if hoop is None:
        return limit
    return limit + 20.0 / hoop * max(1.0, math.sqrt(params.m1 / params.m2))


def _first_step(imp: Impact, first_step: float | str) -> dict[str, float]:
    if first_step == "scipy":
        return {}
    if first_step == "auto":
        return {"first_step": 1e-4 * imp.time_scale()}
    if isinstance(first_step, int | float) and math.isfinite(first_step) and first_step > 0:
        return {"first_step": float(first_step)}
    raise ParameterError("first_step", first_step, "must be 'auto', 'scipy' or a positive number of s")


MAX_CONTACTS = 1000
MAX_FLIGHT_STEPS = 40_000  # free-flight steps allowed in all (~1 s) before refusing
# An explicit method's stability interval on the negative real axis: |h lambda| up to which a decaying
# mode stays damped (the roots of |R(z)| = 1 of the methods' tableaus: DOP853 6.3936, RK45 3.3106).
STABILITY_INTERVAL = {"DOP853": 6.39, "RK45": 3.31}
STEP_ALLOWANCE = 4.0  # what `_Phases.free` allows a step over that limit (measured: 1.000 on average)
FORESEE_AT = (256, 1024, 4096, 16384)  # steps into a free flight at which it looks ahead
FORESEE_SLACK = 1000.0  # solver error `cannot_touch` allows for, in tolerances (rtol, atol)
TINY_AMPLITUDE = 1e-250  # m: a barrel's slow mode above it keeps its fast mode alive (`_foresee`)


def solve_reference(
    imp: Impact,
    method: str = "DOP853",
    rtol: float = 1e-10,
    energy: bool = False,
    first_step: float | str = "auto",
) -> CollisionResult:
    """Solve one collision with solve_ivp, through every contact until the ball leaves for good.

    A contact ends where the contact force returns to zero (the ball cannot pull on the barrel).
    The ball then flies freely while the barrel rings; if the barrel catches it again, a new
    contact begins; this repeats until `equations.escape_time` proves no further contact can
    come. The COR is the ball's speed after the last contact.

    `first_step` "auto" starts at 1e-4 of the contact's time scale, as the kernel does, because
    scipy's own choice ("scipy") is too long for the non-smooth d^b onset of the contact force;
    a number sets it. A brief dip of the force below zero inside one step is found too: the
    minima of g are events, and contact ends at the first one where g < 0.
    """
    if method not in SCIPY_METHODS:
        raise ParameterError("method", method, f"choose one of {', '.join(SCIPY_METHODS)}")
    rtol = check_tolerance(rtol)
    p = imp.params
    y0 = initial_state(imp, energy=energy)
    solver = _Phases(imp, method, rtol, energy, _first_step(imp, first_step))
    t_end, y_end = solver.contact(0.0, y0)
    t_end, y_end, contacts = solver.follow(t_end, y_end)
    v_exit = float(y_end[1])
    terms: dict[str, float] = {}
    if energy:
        terms = mechanical_energy(imp, y_end)
        terms["ball_dissipated"] = float(y_end[imp.n_states])
        terms["barrel_dissipated"] = float(y_end[imp.n_states + 1])
        terms["ball_released"] = solver.released  # elastic energy dropped between contacts
        terms["inbound_kinetic"] = 0.5 * p.m1 * imp.speed**2
        out = sum(v for k, v in terms.items() if k != "inbound_kinetic")
        terms["residual"] = terms["inbound_kinetic"] - out
    return CollisionResult(
        cor=bounded_cor(-v_exit / imp.speed),
        contact_time_s=t_end,
        ball_exit_velocity=v_exit,
        final_state=tuple(float(v) for v in y_end[: imp.n_states]),
        nfev=solver.nfev,
        method=method,
        rtol=rtol,
        energy=terms,
        contacts=contacts,
    )


def bounded_cor(cor: float) -> float:
    """|COR| <= 1: a passive barrel cannot return more than the ball's energy; the solvers' last
    digits (a few rtol) can, so the reported COR is clipped to [-1, 1]."""
    return min(1.0, max(-1.0, cor))


def continue_contacts(
    imp: Impact,
    t: float,
    state: ArrayLike,
    rtol: float,
    method: str = "DOP853",
    budget: int = MAX_FLIGHT_STEPS,
    foresee: bool = True,
) -> tuple[float, np.ndarray, int, int]:
    """From the end of a first contact (time t, mechanical state), follow every later contact.

    Returns (time of the last separation, state there, number of contacts, nfev spent here).
    `budget`: free-flight steps allowed in all; `foresee`: refuse as soon as a flight is proved
    to need more (`_Phases.free`), rather than after stepping through the budget (same refusals).
    """
    rtol = check_tolerance(rtol)
    solver = _Phases(imp, method, rtol, False, _first_step(imp, "auto"), budget, foresee)
    y = np.asarray(state, dtype=float)[: imp.n_states].copy()
    t_end, y_end, contacts = solver.follow(float(t), y)
    return t_end, y_end, contacts, solver.nfev


class _Phases:
    """Contact phases (full equations, end where g falls through 0) and free flights (no contact
    force, end where a new contact begins or when the ball is out of reach for good)."""

    def __init__(
        self,
        imp: Impact,
        method: str,
        rtol: float,
        energy: bool,
        options: dict[str, float],
        budget: int = MAX_FLIGHT_STEPS,
        foresee: bool = True,
    ) -> None:
        p = imp.params
        self.imp, self.method, self.rtol, self.options = imp, method, rtol, options
        self.budget, self.foresee = budget, foresee
        rates = creep_rates(imp) if foresee and method in STABILITY_INTERVAL else None
        # the longest average step of a flight (`free`), s: inf where no bound on it is known
        self.stiff_step = math.inf
        if rates is not None:
            self.stiff_step = STEP_ALLOWANCE * STABILITY_INTERVAL[method] / rates[1]
        self.fun = make_rhs(imp, energy=energy)
        self.free_fun = make_rhs(imp, energy=energy, free=True)
        atol = rtol * imp.scales()
        if energy:
            ke0 = 0.5 * p.m1 * imp.speed**2
            atol = np.concatenate([atol, [rtol * ke0, rtol * ke0]])
        self.atol = atol
        self.nfev = 0
        self.flight_steps = 0
        self.released = 0.0  # ball's elastic energy dropped over free flights, J
        self.t_max = _time_limit(imp)
        self.where = f"speed {imp.speed:g} m/s, hoop {imp.hoop_hz or 'rigid'} Hz, {method} rtol {rtol:g}"

    def _solve(self, fun: Any, t0: float, t1: float, y0: np.ndarray, events: list, **extra: Any) -> Any:
        from scipy.integrate import solve_ivp  # on first use: the compiled kernel's solves never need it

        method = cast(ScipyMethod, self.method)  # solve_reference checks it; continue_contacts: DOP853
        try:
            sol = solve_ivp(
                fun, (t0, t1), y0, method=method, rtol=self.rtol, atol=self.atol, events=events, **extra
            )
        except (RuntimeError, ValueError, ZeroDivisionError) as exc:
            raise SolverError(f"scipy {self.method} failed ({exc}) at {self.where}") from None
        self.nfev += int(sol.nfev)
        if sol.status == -1:
            raise SolverError(f"solver failed ({sol.message}) at {self.where}")
        return sol

    def contact(self, t0: float, y0: np.ndarray) -> tuple[float, np.ndarray]:
        """One contact from (t0, y0) to the first zero of the contact force: (t, state)."""
        imp, p, fun = self.imp, self.imp.params, self.fun

        def ended(t: float, y: np.ndarray) -> float:
            d, dd = relative_motion(imp, y)
            g = separation_function(d, dd, p)
            # a new contact starts at g = 0 (to within the event's tolerance): counting its start
            # as g > 0 lets a contact so brief that it ends inside the first step be seen
            return abs(g) + 1e-300 if t == t0 else g  # not 0: brentq would stop there

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
        t_stop = t0 + self.t_max
        options = self.options
        if t0 > 0.0 and imp.hoop_hz is not None:
            # a later contact may be a brief touch of a ringing barrel: steps short enough to see it end
            options = dict(options, max_step=1.0 / (32.0 * imp.hoop_hz))
        sol = self._solve(fun, t0, t_stop, y0, [ended, dip], **options)
        t_last = t_stop
        if sol.status == 1 and len(sol.t_events[0]):
            t_sep = float(sol.t_events[0][0])
            for t_m, y_m in zip(sol.t_events[1], sol.y_events[1], strict=True):
                if t0 < t_m < t_sep and separation_function(*relative_motion(imp, y_m), p) < 0.0:
                    # F dipped below zero inside one step: contact really ended before t_m
                    t_last = float(t_m)
                    sol = self._solve(fun, t0, t_last, y0, [ended, dip], **options)
                    break
        if sol.status != 1 or len(sol.t_events[0]) == 0:
            raise SolverError(f"contact did not end within {self.t_max:.3g} s at {self.where}")
        if len(sol.t) >= 3:
            # The end is located on the dense output of the step that holds it; with b ~ 0 the
            # relative motion decays at ~c1/m fast enough that a stable step is far too long for
            # its interpolant (the kernel's _damping_rate). Retake that step short enough.
            t_prev, y_prev = float(sol.t[-2]), sol.y[:, -2]
            lam = damping_rate(imp, y_prev)
            kappa = min(1.0, (40320.0 * self.rtol) ** 0.125)
            h_est = max(float(sol.t[-1]) - t_prev, t_prev - float(sol.t[-3]))
            if lam * h_est > kappa and self.method in ("DOP853", "RK45"):  # explicit methods only
                extra = dict(options, max_step=min(0.9 * kappa / lam, options.get("max_step", math.inf)))
                extra.pop("first_step", None)
                t_last = min(t_last, float(sol.t[-1]) + 2.0 * h_est)
                sol = self._solve(fun, t_prev, t_last, y_prev, [ended, dip], **extra)
                if sol.status != 1 or len(sol.t_events[0]) == 0:
                    raise SolverError(f"contact did not end within {self.t_max:.3g} s at {self.where}")
        t_end = float(sol.t_events[0][0])
        if t_end < t0 or (t_end == 0.0 and t0 == 0.0):
            raise SolverError(f"contact ended at t = {t_end!r} (before it began) at {self.where}")
        if t_end == t0:
            return t0, y0  # a graze: the force touched zero from below and fell back
        y_end = np.asarray(sol.y_events[0][0], dtype=float)
        if not np.all(np.isfinite(y_end)):
            raise SolverError(f"non-finite state at separation at {self.where}")
        return t_end, y_end

    def free(self, t0: float, y0: np.ndarray, horizon: float) -> tuple[bool, float, np.ndarray]:
        """Free flight from a separation for at most `horizon` s: (met again?, t, state).

        A flight that would spend the step budget is refused ("creeps off"), either when the budget
        is spent (`_spend`) or as soon as it is foreseen (`_foresee`), at FORESEE_AT steps into it.
        """
        imp = self.imp
        # short steps so that a brief new contact cannot hide inside one step
        period = math.inf if imp.hoop_hz is None else 1.0 / imp.hoop_hz
        # (capped at 20000 steps a flight: a creeping ball on a stiff ringing barrel can take
        # ~1e5 barrel periods to get out of reach; there a contact shorter than a step may be missed)
        max_step = max(min(period / 32.0, 50.0 * imp.time_scale()), horizon / 20000.0)
        longest = min(max_step, self.stiff_step)  # average step, s
        seen = [-math.inf, 0]  # the last step's end, steps so far

        def met(t: float, y: np.ndarray) -> float:
            self._spend()
            if self.foresee and t > seen[0]:  # a step's end (a root search looks inside the last step)
                seen[0] = t
                seen[1] += 1
                if seen[1] in FORESEE_AT:
                    self._foresee(t, y, t0 + horizon, longest)
            # the flight starts at g = 0 (to within the event's tolerance): counting its start as
            # out of contact lets a gap so brief that it closes inside the first step be seen
            c = contact_indicator(imp, y)
            return -abs(c) - 1e-300 if t == t0 else c  # not 0: brentq would stop there

        met.terminal = True  # type: ignore[attr-defined]
        met.direction = 1  # type: ignore[attr-defined]

        def peak(t: float, y: np.ndarray) -> float:
            return relative_motion(imp, y)[1]  # d' falling through 0: a maximum of the overlap d

        peak.direction = -1  # type: ignore[attr-defined]
        sol = self._solve(self.free_fun, t0, t0 + horizon, y0, [met, peak], max_step=max_step)
        t_met = float(sol.t_events[0][0]) if sol.status == 1 and len(sol.t_events[0]) else math.inf
        for t_p, y_p in zip(sol.t_events[1], sol.y_events[1], strict=True):
            # A graze (the barrel barely catching the ball) can be far shorter than a step, so the
            # indicator is negative at both ends of the step that holds it; but d peaks inside
            # it, and d' changes sign over a long time, so the peak is found. d > 0 there: contact.
            if t_p >= t_met:
                break
            if contact_indicator(imp, y_p) > 0.0:
                return True, *self._contact_start(sol, t0, y0, float(t_p), max_step)
        if math.isfinite(t_met):
            return True, t_met, np.asarray(sol.y_events[0][0], dtype=float)
        return False, float(sol.t[-1]), np.asarray(sol.y[:, -1], dtype=float)

    def _contact_start(
        self, sol: Any, t0: float, y0: np.ndarray, t_peak: float, max_step: float
    ) -> tuple[float, np.ndarray]:
        """Where the indicator rises through 0 before a peak of d inside the contact: the step that
        holds the peak is solved again with its dense output (only then: it costs ~20 %)."""
        imp = self.imp
        k = int(np.searchsorted(sol.t, t_peak)) - 1
        t_lo, y_lo = (float(sol.t[k]), sol.y[:, k]) if k >= 0 else (t0, y0)
        again = self._solve(self.free_fun, t_lo, t_peak, y_lo, [], max_step=max_step, dense_output=True)

        def level(t: float) -> float:
            return contact_indicator(imp, again.sol(t))

        if t_lo <= t0 or level(t_lo) >= 0.0:
            t_lo = t_lo + 1e-9 * (t_peak - t_lo)
        if level(t_lo) >= 0.0:
            return t_lo, np.asarray(again.sol(t_lo), dtype=float)
        from scipy.optimize import brentq

        t_c = brentq(level, t_lo, t_peak, xtol=1e-14 * max(1.0, t_peak), rtol=4.0 * np.finfo(float).eps)
        return float(t_c), np.asarray(again.sol(t_c), dtype=float)

    def _spend(self) -> None:
        """Count a step of a free flight; refuse once the budget is spent."""
        self.flight_steps += 1
        if self.flight_steps > self.budget:
            raise SolverError(
                f"the ball creeps off for more than {self.budget} steps of free flight (a very slow"
                f" rebound from a stiff or over-damped barrel) at {self.where}"
            )

    def _foresee(self, t: float, y: np.ndarray, t_end: float, longest: float) -> None:
        """Refuse now, at a step's end (t, y) of a flight that ends at t_end at the latest, if it is
        certain to spend the rest of the step budget before a new contact or its end.

        Every step is at most `longest`: the flight's max_step, or STEP_ALLOWANCE times an explicit
        method's stability limit beta / f on an over-damped barrel (f its fast decay rate). That limit
        holds on average, not for each step: a longer step multiplies the barrel's fast mode by
        |R(-f h)| > 1, and the error control rejects steps until the mode has decayed again. Measured
        on such flights (the 0.1 g barrel at 100 Hz, f = 1e6 /s; DOP853 and RK45, rtol 1e-2 to 1e-13,
        the barrel's amplitude 1e-300 m to 0.1 m): the average over any 500 steps is beta / f to 4
        digits, though single steps reach ~20 times it (DOP853; RK45 up to its max_step). Only a barrel
        exactly at rest (no fast mode at all) steps further; its amplitude would have to underflow
        within the window, ruled out below. Where max_step is the shorter, the bound holds for every
        step and any method.

        So the rest of the budget, n steps, covers at most (n + 1) longest s. If the flight cannot end
        sooner (t_end beyond that) and `equations.cannot_touch` proves that no contact can begin in
        that window (allowing for FORESEE_SLACK times the solver's tolerances), the flight would
        spend the budget: refused as `_spend` would refuse it, without stepping there.
        """
        left = self.budget - self.flight_steps
        window = (left + 1) * longest
        if t + window >= t_end:
            return
        rates = creep_rates(self.imp)
        if rates is None:
            return
        slow, fast = rates
        slow_mode = (fast * float(y[2]) + float(y[3])) / (fast - slow)  # the barrel's A exp(-slow t)
        if longest >= self.stiff_step and not abs(slow_mode) * math.exp(-slow * window) > TINY_AMPLITUDE:
            return
        rel = FORESEE_SLACK * self.rtol
        if cannot_touch(self.imp, y, window, rel, FORESEE_SLACK * self.atol[2], FORESEE_SLACK * self.atol[3]):
            raise SolverError(
                f"the ball creeps off for more than {self.budget} steps of free flight (a very slow"
                f" rebound from a stiff or over-damped barrel; foreseen after {self.flight_steps} steps:"
                f" its steps average {longest:.3g} s at most) at {self.where}"
            )

    def _stored(self, y: np.ndarray) -> float:
        return mechanical_energy(self.imp, y)["ball_stored"]

    def follow(self, t: float, y: np.ndarray) -> tuple[float, np.ndarray, int]:
        """From the end of the first contact through every later one: (t, state, contacts)."""
        contacts = rounds = 1
        while True:
            wait = escape_time(self.imp, y)
            if wait == 0.0:
                return t, y, contacts
            horizon = wait if math.isfinite(wait) else 100.0 * self.t_max
            met, t_free, y_free = self.free(t, y, horizon)
            if not met:
                if math.isfinite(wait):
                    return t, y, contacts  # out of reach for good, the ball's speed unchanged
                raise SolverError(
                    f"the ball neither left nor met the barrel again within {horizon:.3g} s at {self.where}"
                )
            rounds += 1
            if rounds > MAX_CONTACTS:
                raise SolverError(f"more than {MAX_CONTACTS} contacts at {self.where}")
            # the model keeps no account of the ball's shape out of contact: the elastic energy
            # it held when it left is dropped, and what its overlap d holds when it meets the
            # barrel again is counted anew
            self.released += self._stored(y) - self._stored(y_free)
            t, y = self.contact(t_free, y_free)
            if t > t_free:
                contacts += 1


def momentum(imp: Impact, state: tuple[float, ...] | np.ndarray) -> float:
    """Total momentum of the free bodies (meaningful when the base is free), kg m/s."""
    p = imp.params
    y = np.asarray(state, dtype=float)
    if imp.body_mass is None:
        return math.nan
    if imp.rigid:
        return p.m1 * y[1] + (p.m2 + imp.body_mass) * y[3]
    return p.m1 * y[1] + p.m2 * y[3] + imp.body_mass * y[5]
