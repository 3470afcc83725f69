"""What accuracy costs: the work-precision sweep of the collision solvers.

For each solver and tolerance: the error in COR and contact time against a reference that two
unrelated methods agree on (scipy DOP853 and Radau at rtol 1e-13) and the number of right-hand-side
evaluations; both are machine-independent. A DETEST-style fit of error = C * rtol^p per method says
how well each one honours its tolerance. The sweep is pure: the wall time per solve comes from an
injected `Timer` (studies.accuracy.stopwatch; benchmarks/timing.py has the careful one), and
without one the times are NaN. The efficiency curve's trade-off is studies.accuracy.curve_cost;
the first-step probe studies.accuracy.first_step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol, TypeVar

import numpy as np

from rig.core.errors import ParameterError, SolverError
from rig.physics import fast
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

R = TypeVar("R")


class Timer(Protocol):
    """Times a solve: calls it once (a warm-up whose result is kept), then measures seconds per call."""

    repeats: int  # timed batches per solve, recorded with the study

    def __call__(self, solve: Callable[[], R]) -> tuple[R, float]:
        """(result of the first call, seconds per call)."""
        ...


def timed(solve: Callable[[], R], timer: Timer | None) -> tuple[R, float]:
    """The solve's result and its time per call (NaN without a timer: the sweep itself reads no clock)."""
    return (solve(), math.nan) if timer is None else timer(solve)


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
    time_s: float  # best-of-N wall time of one solve, after a warm-up solve (NaN: not timed)

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
    repeats: int = 0  # timed batches per solve (0: not timed)
    elapsed_s: float = math.nan  # wall time of the whole study (studies.accuracy.stopwatch.stamped)

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
    speed: float = 60.8,
    hoops: tuple[float | None, ...] = (1250.0, 5000.0),
    methods: tuple[str, ...] | None = None,
    rtols: tuple[float, ...] | None = None,
    implicit_rtols: tuple[float, ...] | None = None,
    params: CollisionParams = DEFAULT_PARAMS,
    timer: Timer | None = None,
) -> PrecisionStudy:
    """Error in COR and contact time against cost, per method and tolerance, for each hoop case.

    quick: one hoop case, three tolerances and five methods (a smoke run for tests).
    rtols / implicit_rtols override the sweeps of the explicit (and LSODA) and the implicit methods.
    timer: how a solve is timed (studies.accuracy.stopwatch); None leaves the times NaN.
    """
    speed = check_speed(speed)
    if not hoops:
        raise ParameterError("hoops", hoops, "must name at least one hoop frequency (None: rigid)")
    if quick:
        hoops = hoops[:1]
    methods = methods or (QUICK_METHODS if quick else METHODS)
    for m in methods:
        if m not in METHODS:
            raise ParameterError("method", m, f"choose from {', '.join(METHODS)}")
    explicit = tuple(check_tolerance(r) for r in (rtols or (QUICK_RTOLS if quick else EXPLICIT_RTOLS)))
    implicit = tuple(
        check_tolerance(r) for r in (implicit_rtols or (QUICK_IMPLICIT_RTOLS if quick else IMPLICIT_RTOLS))
    )
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
                # the first (warm-up) solve gives the errors; the timer's batches only the cost
                res, seconds = timed(_solver(method, imp, rtol), timer)
                row = PrecisionRow(
                    method=method,
                    rtol=rtol,
                    hoop_hz=hoop,
                    speed=speed,
                    cor=res.cor,
                    cor_error=abs(res.cor - ref.cor),
                    contact_time_error=abs(res.contact_time_s - ref.contact_time_s) / ref.contact_time_s,
                    nfev=res.nfev,
                    time_s=seconds,
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
        repeats=0 if timer is None else timer.repeats,
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


__all__ = [
    "IMPLICIT",
    "KERNEL",
    "METHODS",
    "PrecisionRow",
    "PrecisionStudy",
    "ReferenceValue",
    "Timer",
    "ToleranceFit",
    "cost_to_reach",
    "reference_value",
    "reliable_rtol",
    "timed",
    "tolerance_fit",
    "work_precision",
]
