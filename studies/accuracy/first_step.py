"""Why the compiled kernel beats scipy's DOP853 (the same method) at loose tolerance: the first step.

A probe of the accuracy study (docs/accuracy.md): scipy's DOP853 with its own first step and with
the kernel's, against the kernel, at a few tolerances. Errors and evaluation counts only, no timing.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from rig.core.errors import SolverError
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.reference import solve_reference
from studies.accuracy.precision import REFERENCE_RTOL


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
        # scipy takes an array atol and a fun returning a list; scipy-stubs declare float and ndarray
        h_scipy = DOP853(fun, 0.0, y0, t_max, rtol=rtol, atol=atol).h_abs  # type: ignore[arg-type]
        runs = []
        for first in (None, h_kernel):
            sol = solve_ivp(
                fun, (0.0, t_max), y0, "DOP853", rtol=rtol, atol=atol, events=ended, first_step=first
            )
            if sol.status != 1 or sol.y_events is None:  # status 1: a terminal event, so y_events is set
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


__all__ = ["FirstStepRow", "first_step_effect"]
