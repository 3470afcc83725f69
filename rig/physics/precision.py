"""What accuracy costs in time: work-precision study of the collision solvers.

For each solver and tolerance: the error in COR and contact time against a reference that two
unrelated methods agree on (scipy DOP853 and Radau at rtol 1e-13), the number of right-hand-side
evaluations (machine-independent) and the best-of-N wall time per solve after a warm-up solve.
A DETEST-style fit of error = C * rtol^p per method says how well each one honours its tolerance.
The same trade-off is measured for the efficiency curve (grid density and tolerance).
The harness that describes the machine, pauses the collector while timing and writes
docs/accuracy.md lives in benchmarks/ (timing.py, accuracy_writer.py), not in the package.
Longer than 400 lines because the study's record types, sweeps and fits share their constants and
are read together.
"""

from __future__ import annotations

import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rig.core.errors import ParameterError, SolverError
from rig.physics import fast
from rig.physics.curve import EfficiencyCurve, cor_grid, efficiency_curve, rigid_cor
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS, CollisionParams, check_speed, check_tolerance
from rig.physics.reference import SCIPY_METHODS, CollisionResult, solve_reference

KERNEL = "rig-DOP853"
METHODS = (KERNEL, *SCIPY_METHODS)
IMPLICIT = ("Radau", "BDF")
REFERENCE_RTOL = 1e-13
REFERENCE_AGREEMENT = 1e-10  # the two reference methods must agree on COR to this
# Explicit methods and LSODA: 1e-4 ... 1e-12 in half decades (the Hairer-Wanner driver spacing).
EXPLICIT_RTOLS = tuple(10.0 ** (-k / 2) for k in range(8, 25))
# Radau and BDF cost 5-20x more per solve than DOP853 here: decades, and no tighter than 1e-10.
IMPLICIT_RTOLS = tuple(10.0**-k for k in range(4, 11))
QUICK_METHODS = (KERNEL, "DOP853", "RK45", "LSODA", "Radau")
QUICK_RTOLS = (1e-4, 1e-7, 1e-10)
QUICK_IMPLICIT_RTOLS = (1e-4, 1e-6)
MIN_TIMED_S = 0.01  # a timed batch of solves lasts at least this long (perf_counter resolution, jitter)
QUICK_MIN_TIMED_S = 0.002
MAX_LOOP = 2000


@dataclass(frozen=True)
class PrecisionRow:
    """One solver at one tolerance on one case: its errors against the reference and its cost."""

    method: str
    rtol: float
    hoop_hz: float | None  # None: rigid barrel
    speed: float
    cor: float
    cor_error: float  # |cor - cor_ref|
    contact_time_error: float  # |t_c - t_c,ref| / t_c,ref
    nfev: int
    time_s: float  # best-of-N wall time of one solve, after a warm-up solve

    def as_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the row."""
        return asdict(self)


@dataclass(frozen=True)
class ReferenceValue:
    """The reference solution of one case and how far the two reference methods disagree."""

    speed: float
    hoop_hz: float | None
    cor: float  # scipy DOP853 at REFERENCE_RTOL: the value errors are measured against
    contact_time_s: float
    cor_radau: float  # Radau at REFERENCE_RTOL: an unrelated (implicit) method, as a check
    contact_time_radau_s: float
    cor_disagreement: float  # |cor - cor_radau|
    contact_time_disagreement: float  # relative
    rtol: float

    def as_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the reference."""
        return asdict(self)


@dataclass(frozen=True)
class ToleranceFit:
    """Least-squares fit of cor_error = C * rtol^p on log-log axes (DETEST's tolerance proportionality)."""

    method: str
    hoop_hz: float | None
    exponent: float  # p: 1 means the error follows the tolerance; below 1, tightening buys less
    constant: float  # C: the error at rtol = 1 by extrapolation
    points: int  # rows used (those with an error above the reference's own uncertainty)
    rms_log10_residual: float  # scatter about the fit, decades

    def as_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the fit."""
        return asdict(self)


@dataclass(frozen=True)
class PrecisionStudy:
    """Rows of the work-precision study, with its references, fits and machine."""

    rows: tuple[PrecisionRow, ...]
    references: tuple[ReferenceValue, ...]
    tolerance_fits: tuple[ToleranceFit, ...]
    environment: dict[str, Any] = field(default_factory=dict)
    repeats: int = 1
    elapsed_s: float = math.nan  # wall time of the whole study

    def as_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the whole study."""
        return {
            "rows": [r.as_dict() for r in self.rows],
            "references": [r.as_dict() for r in self.references],
            "tolerance_fits": [f.as_dict() for f in self.tolerance_fits],
            "environment": dict(self.environment),
            "repeats": self.repeats,
            "elapsed_s": self.elapsed_s,
        }

    def methods(self) -> tuple[str, ...]:
        """Methods in the order they were run."""
        return tuple(dict.fromkeys(r.method for r in self.rows))

    def cases(self) -> tuple[float | None, ...]:
        """Hoop frequencies in the order they were run (None: rigid)."""
        return tuple(dict.fromkeys(r.hoop_hz for r in self.rows))


@dataclass(frozen=True)
class CurveTradeoffRow:
    """Cost and accuracy of one efficiency curve (grid density, tolerance)."""

    points: int
    rtol: float
    time_s: float  # best-of-N wall time of efficiency_curve: grid, rigid COR and refined optimum
    grid_time_s: float  # best-of-N wall time of the grid alone (cor_grid)
    max_eta_error: float  # max |eta - eta_ref| over the grid points
    grid_optimum_error_hz: float  # |best grid point - reference optimum|: what refinement removes
    optimum_hz: float
    optimum_error_hz: float  # |refined optimum - reference optimum|
    optimum_efficiency_error: float

    def as_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the row."""
        return asdict(self)


Timer = Callable[[Callable[[], object], int, float, "float | None"], float]
"""(solve, repeats, min_time_s, once_s) -> seconds per call; benchmarks/timing.py has the careful one."""


def versions() -> dict[str, Any]:
    """Interpreter and library versions: timings mean nothing without them (the machine itself is
    described by the benchmark harness)."""
    import numba
    import scipy

    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
    }


def time_per_call(
    solve: Callable[[], object], repeats: int, min_time_s: float = MIN_TIMED_S, once_s: float | None = None
) -> float:
    """Best-of-`repeats` seconds per call of `solve` (already warmed up); fast calls are looped."""
    return best_batch(solve, repeats, calls_per_batch(solve, min_time_s, once_s))


def calls_per_batch(solve: Callable[[], object], min_time_s: float, once_s: float | None = None) -> int:
    """How many calls make a timed batch last `min_time_s` (well above the timer's resolution).

    once_s: the duration of one earlier call, if known; it sizes the loop instead of a calibrating call.
    """
    once = once_s
    if once is None or once < min_time_s:
        t0 = time.perf_counter()
        solve()
        once = time.perf_counter() - t0
    return max(1, min(MAX_LOOP, math.ceil(min_time_s / max(once, 1e-9))))


def best_batch(solve: Callable[[], object], repeats: int, number: int) -> float:
    """Seconds per call of the fastest of `repeats` batches of `number` calls."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(number):
            solve()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def _solver(method: str, imp: Impact, rtol: float) -> Callable[[], CollisionResult]:
    if method == KERNEL:
        return lambda: fast.solve(imp, rtol)
    if method not in SCIPY_METHODS:
        raise ParameterError("method", method, f"choose from {', '.join(METHODS)}")
    return lambda: solve_reference(imp, method=method, rtol=rtol, first_step="scipy")


def reference_value(imp: Impact) -> ReferenceValue:
    """Reference COR and contact time from DOP853 and Radau at rtol 1e-13; SolverError if they disagree."""
    dop = solve_reference(imp, method="DOP853", rtol=REFERENCE_RTOL, first_step="scipy")
    rad = solve_reference(imp, method="Radau", rtol=REFERENCE_RTOL, first_step="scipy")
    gap = abs(dop.cor - rad.cor)
    tc_gap = abs(dop.contact_time_s - rad.contact_time_s) / dop.contact_time_s
    if not gap <= REFERENCE_AGREEMENT:
        hoop = "rigid" if imp.hoop_hz is None else f"{imp.hoop_hz:g} Hz"
        raise SolverError(
            f"reference methods disagree at speed {imp.speed:g} m/s, hoop {hoop}: DOP853 COR {dop.cor!r},"
            f" Radau COR {rad.cor!r} (|difference| {gap:.3g} > {REFERENCE_AGREEMENT:g})"
        )
    return ReferenceValue(
        speed=imp.speed,
        hoop_hz=imp.hoop_hz,
        cor=dop.cor,
        contact_time_s=dop.contact_time_s,
        cor_radau=rad.cor,
        contact_time_radau_s=rad.contact_time_s,
        cor_disagreement=gap,
        contact_time_disagreement=tc_gap,
        rtol=REFERENCE_RTOL,
    )


def tolerance_fit(rows: tuple[PrecisionRow, ...], floor: float = 0.0) -> ToleranceFit | None:
    """Fit cor_error = C rtol^p over rows (one method, one case) with an error above `floor`."""
    used = [r for r in rows if r.cor_error > floor and math.isfinite(r.cor_error)]
    if len({r.rtol for r in used}) < 2:
        return None
    x = np.log10([r.rtol for r in used])
    y = np.log10([r.cor_error for r in used])
    p, logc = np.polyfit(x, y, 1)
    resid = y - (p * x + logc)
    return ToleranceFit(
        method=used[0].method,
        hoop_hz=used[0].hoop_hz,
        exponent=float(p),
        constant=float(10.0**logc),
        points=len(used),
        rms_log10_residual=float(np.sqrt(np.mean(resid**2))),
    )


def work_precision(
    quick: bool = False,
    repeats: int = 5,
    speed: float = 60.8,
    hoops: tuple[float | None, ...] = (1250.0, 5000.0),
    methods: tuple[str, ...] | None = None,
    rtols: tuple[float, ...] | None = None,
    implicit_rtols: tuple[float, ...] | None = None,
    params: CollisionParams = DEFAULT_PARAMS,
    timer: Timer = time_per_call,
) -> PrecisionStudy:
    """Error in COR and contact time against cost, per method and tolerance, for each hoop case.

    quick: one hoop case, three tolerances, five methods and one timed repeat (a smoke run for tests).
    rtols / implicit_rtols override the sweeps of the explicit (and LSODA) and the implicit methods.
    timer: how a solve is timed (benchmarks/timing.py's `best_time` also pauses the collector).
    """
    started = time.perf_counter()
    speed = check_speed(speed)
    if not isinstance(repeats, int) or repeats < 1:
        raise ParameterError("repeats", repeats, "must be a whole number >= 1")
    if not hoops:
        raise ParameterError("hoops", hoops, "must name at least one hoop frequency (None: rigid)")
    if quick:
        hoops = hoops[:1]
        repeats = 1
    methods = methods or (QUICK_METHODS if quick else METHODS)
    for m in methods:
        if m not in METHODS:
            raise ParameterError("method", m, f"choose from {', '.join(METHODS)}")
    explicit = tuple(check_tolerance(r) for r in (rtols or (QUICK_RTOLS if quick else EXPLICIT_RTOLS)))
    implicit = tuple(
        check_tolerance(r) for r in (implicit_rtols or (QUICK_IMPLICIT_RTOLS if quick else IMPLICIT_RTOLS))
    )
    min_time = QUICK_MIN_TIMED_S if quick else MIN_TIMED_S
    fast.warm_up()  # load or compile the kernel before anything is timed

    rows: list[PrecisionRow] = []
    refs: list[ReferenceValue] = []
    fits: list[ToleranceFit] = []
    for hoop in hoops:
        imp = Impact(params, speed, hoop)
        ref = reference_value(imp)
        refs.append(ref)
        for method in methods:
            case_rows = []
            for rtol in implicit if method in IMPLICIT else explicit:
                solve = _solver(method, imp, rtol)
                t0 = time.perf_counter()
                res = solve()  # the warm-up solve; its result gives the errors, timing is separate
                once = time.perf_counter() - t0
                row = PrecisionRow(
                    method=method,
                    rtol=rtol,
                    hoop_hz=hoop,
                    speed=speed,
                    cor=res.cor,
                    cor_error=abs(res.cor - ref.cor),
                    contact_time_error=abs(res.contact_time_s - ref.contact_time_s) / ref.contact_time_s,
                    nfev=res.nfev,
                    time_s=timer(solve, repeats, min_time, once),
                )
                case_rows.append(row)
            rows.extend(case_rows)
            # Errors at or below the references' own disagreement are noise, not solver error.
            fit = tolerance_fit(tuple(case_rows), floor=ref.cor_disagreement)
            if fit is not None:
                fits.append(fit)
    return PrecisionStudy(
        rows=tuple(rows),
        references=tuple(refs),
        tolerance_fits=tuple(fits),
        environment=versions(),
        repeats=repeats,
        elapsed_s=time.perf_counter() - started,
    )


def reliable_rtol(rows: tuple[PrecisionRow, ...], target: float) -> PrecisionRow | None:
    """The loosest-tolerance row of one method and case from which on every tighter row has error <= target.

    A lucky loose tolerance that happens to hit the target, with a tighter one missing it, does not
    count: a user choosing a tolerance cannot know about the luck in advance.
    """
    ordered = sorted(rows, key=lambda r: -r.rtol)
    found = None
    for row in reversed(ordered):
        if row.cor_error > target:
            break
        found = row
    return found


def cost_to_reach(
    study: PrecisionStudy, target: float, hoop_hz: float | None
) -> dict[str, PrecisionRow | None]:
    """Per method, the row (tolerance, time, nfev) that reliably reaches |COR error| <= target on one case."""
    out: dict[str, PrecisionRow | None] = {}
    for method in study.methods():
        rows = tuple(r for r in study.rows if r.method == method and r.hoop_hz == hoop_hz)
        out[method] = reliable_rtol(rows, target) if rows else None
    return out


@dataclass(frozen=True)
class FirstStepRow:
    """scipy DOP853 with its own first step and with the compiled kernel's, at one tolerance."""

    rtol: float
    scipy_first_step_s: float  # what solve_ivp's select_initial_step picks
    kernel_first_step_s: float  # 1e-4 * compression scale / v0, as in _dop853.solve_one
    cor_error_default: float
    nfev_default: int
    cor_error_kernel_step: float
    nfev_kernel_step: int
    kernel_cor_error: float  # the compiled kernel itself, for comparison
    kernel_nfev: int

    def as_dict(self) -> dict[str, Any]:
        """A JSON-safe dict of the row."""
        return asdict(self)


def first_step_effect(
    imp: Impact, rtols: tuple[float, ...] = (1e-4, 1e-6, 1e-8, 1e-10), cor_ref: float | None = None
) -> tuple[FirstStepRow, ...]:
    """Why the kernel beats scipy's DOP853 (the same method) at loose tolerance: the first step.

    The contact force grows like d^b at impact (not Lipschitz), so the error of the first steps
    depends on where they land; solve_ivp's initial-step heuristic proposes about the whole contact.
    """
    from scipy.integrate import solve_ivp
    from scipy.integrate._ivp.rk import DOP853

    from rig.physics.equations import initial_state, make_rhs, relative_motion, separation_function
    from rig.physics.reference import _time_limit

    p = imp.params
    ref = (
        cor_ref
        if cor_ref is not None
        else solve_reference(imp, "DOP853", REFERENCE_RTOL, first_step="scipy").cor
    )
    fun, y0, t_max = make_rhs(imp), initial_state(imp), _time_limit(imp)
    h_kernel = 1e-4 * p.compression_scale(imp.speed) / imp.speed

    def ended(t: float, y: np.ndarray) -> float:
        d, dd = relative_motion(imp, y)
        return separation_function(d, dd, p)

    ended.terminal = True  # type: ignore[attr-defined]
    ended.direction = -1  # type: ignore[attr-defined]
    out = []
    for rtol in rtols:
        atol = rtol * imp.scales()
        h_scipy = DOP853(fun, 0.0, y0, t_max, rtol=rtol, atol=atol).h_abs
        runs = []
        for first in (None, h_kernel):
            sol = solve_ivp(
                fun, (0.0, t_max), y0, "DOP853", rtol=rtol, atol=atol, events=ended, first_step=first
            )
            if sol.status != 1:
                raise SolverError(f"first-step probe: contact did not end ({sol.message})")
            runs.append((float(abs(-sol.y_events[0][0][1] / imp.speed - ref)), int(sol.nfev)))
        k = fast.solve(imp, rtol)
        out.append(
            FirstStepRow(
                rtol=rtol,
                scipy_first_step_s=float(h_scipy),
                kernel_first_step_s=h_kernel,
                cor_error_default=runs[0][0],
                nfev_default=runs[0][1],
                cor_error_kernel_step=runs[1][0],
                nfev_kernel_step=runs[1][1],
                kernel_cor_error=abs(k.cor - ref),
                kernel_nfev=k.nfev,
            )
        )
    return tuple(out)


def curve_tradeoff(
    speed: float = 60.8,
    hoop_min: float = 300.0,
    hoop_max: float = 20000.0,
    points: tuple[int, ...] = (25, 50, 100, 250, 1000),
    rtols: tuple[float, ...] = (1e-6, 1e-8, 1e-10),
    quick: bool = False,
    repeats: int = 5,
    reference_points: int = 2001,
    params: CollisionParams = DEFAULT_PARAMS,
    timer: Timer = time_per_call,
) -> tuple[CurveTradeoffRow, ...]:
    """Cost and accuracy of the efficiency curve for each grid density and tolerance.

    eta errors are against cor_grid at rtol 1e-13 on the same grid; optimum errors against
    efficiency_curve on `reference_points` points at rtol 1e-12, refined. quick: 2 x 2 runs, 1 repeat.
    """
    speed = check_speed(speed)
    if quick:
        points, rtols, repeats, reference_points = (25, 100), (1e-6, 1e-10), 1, 401
    if not isinstance(repeats, int) or repeats < 1:
        raise ParameterError("repeats", repeats, "must be a whole number >= 1")
    min_time = QUICK_MIN_TIMED_S if quick else MIN_TIMED_S
    fast.warm_up()
    ref_curve = efficiency_curve(params, speed, hoop_min, hoop_max, reference_points, rtol=1e-12)
    if not ref_curve.optimum_interior:
        raise SolverError(f"no interior optimum between {hoop_min:g} and {hoop_max:g} Hz at {speed:g} m/s")
    e_rigid_ref = rigid_cor(params, speed, rtol=REFERENCE_RTOL)
    rows = []
    for n in points:
        hoops = np.linspace(hoop_min, hoop_max, n)
        eta_ref = cor_grid(params, speed, hoops, rtol=REFERENCE_RTOL)[0] / e_rigid_ref
        for rtol in rtols:
            rtol = check_tolerance(rtol)

            def whole(n: int = n, rtol: float = rtol) -> EfficiencyCurve:
                return efficiency_curve(params, speed, hoop_min, hoop_max, n, rtol=rtol)

            def grid(hoops: np.ndarray = hoops, rtol: float = rtol) -> object:
                return cor_grid(params, speed, hoops, rtol)

            curve = whole()  # also the warm-up solve of this grid and tolerance
            best_grid = float(hoops[int(np.argmax(curve.efficiency))])
            rows.append(
                CurveTradeoffRow(
                    points=n,
                    rtol=rtol,
                    time_s=timer(whole, repeats, min_time, None),
                    grid_time_s=timer(grid, repeats, min_time, None),
                    max_eta_error=float(np.max(np.abs(curve.efficiency - eta_ref))),
                    grid_optimum_error_hz=abs(best_grid - ref_curve.optimum_hz),
                    optimum_hz=curve.optimum_hz,
                    optimum_error_hz=abs(curve.optimum_hz - ref_curve.optimum_hz),
                    optimum_efficiency_error=abs(curve.optimum_efficiency - ref_curve.optimum_efficiency),
                )
            )
    return tuple(rows)


__all__ = [
    "METHODS",
    "CurveTradeoffRow",
    "FirstStepRow",
    "PrecisionRow",
    "PrecisionStudy",
    "ReferenceValue",
    "ToleranceFit",
    "best_batch",
    "calls_per_batch",
    "cost_to_reach",
    "curve_tradeoff",
    "first_step_effect",
    "reference_value",
    "reliable_rtol",
    "time_per_call",
    "tolerance_fit",
    "versions",
    "work_precision",
]
