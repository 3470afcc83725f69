"""What an efficiency curve costs and how accurate it is, by grid density and solver tolerance.

Errors are machine-independent; the times come from an injected timer (studies.accuracy.stopwatch),
as in the work-precision sweep (studies.accuracy.precision).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from rig.core.errors import SolverError
from rig.physics import fast
from rig.physics.curve import EfficiencyCurve, cor_grid, efficiency_curve, rigid_cor
from rig.physics.params import DEFAULT_PARAMS, CollisionParams, check_speed, check_tolerance
from studies.accuracy.precision import REFERENCE_RTOL, Timer, timed


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


def curve_tradeoff(
    speed: float = 60.8,
    hoop_min: float = 300.0,
    hoop_max: float = 20000.0,
    points: tuple[int, ...] = (25, 50, 100, 250, 1000),
    rtols: tuple[float, ...] = (1e-6, 1e-8, 1e-10),
    quick: bool = False,
    reference_points: int = 2001,
    params: CollisionParams = DEFAULT_PARAMS,
    timer: Timer | None = None,
) -> tuple[CurveTradeoffRow, ...]:
    """Cost and accuracy of the efficiency curve for each grid density and tolerance.

    eta errors are against cor_grid at rtol 1e-13 on the same grid; optimum errors against
    efficiency_curve on `reference_points` points at rtol 1e-12, refined. quick: 2 x 2 runs.
    timer: how the curve and its grid are timed (studies.accuracy.stopwatch); None leaves the times NaN.
    """
    speed = check_speed(speed)
    if quick:
        points, rtols, reference_points = (25, 100), (1e-6, 1e-10), 401
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

            curve, seconds = timed(whole, timer)  # its first call is the warm-up of this grid and rtol
            _, grid_seconds = timed(grid, timer) if timer is not None else (None, math.nan)
            best_grid = float(hoops[int(np.argmax(curve.efficiency))])
            rows.append(
                CurveTradeoffRow(
                    points=n,
                    rtol=rtol,
                    time_s=seconds,
                    grid_time_s=grid_seconds,
                    max_eta_error=float(np.max(np.abs(curve.efficiency - eta_ref))),
                    grid_optimum_error_hz=abs(best_grid - ref_curve.optimum_hz),
                    optimum_hz=curve.optimum_hz,
                    optimum_error_hz=abs(curve.optimum_hz - ref_curve.optimum_hz),
                    optimum_efficiency_error=abs(curve.optimum_efficiency - ref_curve.optimum_efficiency),
                )
            )
    return tuple(rows)


__all__ = ["CurveTradeoffRow", "curve_tradeoff"]
