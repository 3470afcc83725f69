"""Fast solves of the collision model: one at a time or many in parallel lanes.

Wraps the compiled kernel in `_dop853`; results agree with `reference.solve_reference` and carry
the same meaning. The kernel solves the first contact and proves, for nearly every collision,
that the ball cannot meet the barrel again; when it cannot prove it (low hoop frequencies, where
the barrel comes back and hits the ball again) it hands the state at the first separation to
`reference.continue_contacts`, which follows every later contact with scipy's DOP853 (about
20-40 ms a collision, against ~50 us for a kernel solve). The first call in a fresh checkout
compiles the kernel (a few seconds); the machine code is cached on disk for later runs.

numba and the cached machine code take half a second to a second to load, so the kernel loads only when a
solve needs it: the first `INTERPRETED_SOLVES` single solves of a process run the same kernel
source in the interpreter (`_interpreted`, 10-20 ms each, the same numbers), batches and later
solves the compiled kernel. `warm_up` loads the compiled kernel at once. A caller that asks for it
(`solve_batch(..., numpy_lanes=True)`: a cross-check's few hundred solves) gets a batch of at most
`NUMPY_LANES` solves from `_lanes`, the same steps over all the lanes at once as numpy arrays (the
compiled kernel's numbers to the last bit), unless the compiled kernel is loaded already.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any, Protocol

import numpy as np

from rig.core.errors import ParameterError, SolverError
from rig.physics import _interpreted
from rig.physics.equations import Impact
from rig.physics.params import RTOL_MAX, RTOL_MIN, barrel_spring, check_tolerance
from rig.physics.reference import CollisionResult, _time_limit, bounded_cor, continue_contacts

DEFAULT_RTOL = 1e-10
MAX_STEPS = 2_000_000
INTERPRETED_SOLVES = 45  # ~0.55 s of interpreted solves (~12 ms each): what loading numba and the compiled
# kernel costs at the least (0.5-0.6 s measured in a warm process; more when cold). At that break-even a
# process spends at most about twice the least it could have; a simulated BBCOR certification's ~40
# solves stay interpreted (its `rig certify` took 1.0-1.1 s, against 1.5-2.3 s with 20)
INTERPRETED_MAX_STEPS = 2_000  # ~1 s interpreted: a longer solve goes to the compiled kernel (a stiff
# one of 2e6 steps took 4 minutes interpreted, seconds compiled)
SERIES_ORDER = 16  # the contact's body in Taylor series steps of this order, where asked (bench_curve:
# 16 and 20 cost alike, 12 and 24 more)
NUMPY_LANES = 5000  # a batch this small may run in numpy lanes: ~0.4 s, below numba's load (~1 s)
_COMPILED = "rig.physics._dop853"
_interpreted_left = INTERPRETED_SOLVES
_solve_impact: Any = None  # the compiled kernel's lean entry point, once loaded


def compiled() -> ModuleType:
    """The compiled kernel (numba loads here, the first time)."""
    global _interpreted_left, _solve_impact
    from rig.physics import _dop853

    _interpreted_left = 0
    _solve_impact = _dop853.solve_impact  # single solves go straight to it from now on
    return _dop853


def _single() -> ModuleType:
    """The kernel for one solve: the compiled one once loaded or once enough solves were asked for."""
    global _interpreted_left
    if _COMPILED in sys.modules or _interpreted_left <= 0:
        return compiled()
    _interpreted_left -= 1
    return _interpreted.load()


kernel = _interpreted.load()  # the status codes and sizes (the same in both)
_STATUS_OK = kernel.STATUS_OK
_STATUS_TEXT = {
    kernel.STATUS_TIME_LIMIT: "contact did not end within the time limit",
    kernel.STATUS_MAX_STEPS: "step budget exhausted before contact ended",
    kernel.STATUS_STEP_UNDERFLOW: "step size underflow",
    kernel.STATUS_NOT_FINITE: "state became non-finite",
}


def kernel_params(imp: Impact) -> np.ndarray:
    """The kernel's parameter vector for one impact."""
    p = imp.params
    body = imp.body_mass
    inv_body = 0.0 if body is None else 1.0 / body
    inv_base = 0.0 if body is None else 1.0 / (p.m2 + body)
    hoop = imp.hoop_hz  # checked when the Impact was made
    rigid = hoop is None
    k2 = 0.0 if hoop is None else barrel_spring(p.m2, hoop)  # CollisionParams.k2, unchecked again
    return np.array(
        (p.m1, p.k1, p.c1, p.a, p.b, p.m2, k2, p.c2, inv_body, inv_base, 1.0 if rigid else 0.0),
        dtype=np.float64,
    )


def _describe(imp: Impact, rtol: float) -> str:
    hoop = "rigid" if imp.hoop_hz is None else f"{imp.hoop_hz:g} Hz"
    return f"speed {imp.speed:g} m/s, hoop {hoop}, rtol {rtol:g}"


def solve(imp: Impact, rtol: float = DEFAULT_RTOL) -> CollisionResult:
    """Solve one collision with the DOP853 kernel (interpreted at first, then compiled: see above)."""
    if not (type(rtol) is float and RTOL_MIN <= rtol <= RTOL_MAX):  # the common case in three comparisons
        rtol = check_tolerance(rtol)
    if _solve_impact is None:
        module = _single()
        if module.__name__ != _COMPILED:
            done = _interpreted_solve(imp, rtol, module)
            if done is not None:
                return done
            compiled()  # a long solve: the compiled kernel takes it from the start
    p, hoop, body = imp.params, imp.hoop_hz, imp.body_mass
    out = _solve_impact(
        p.m1,
        p.k1,
        p.c1,
        p.a,
        p.b,
        p.m2,
        p.c2,
        hoop or 0.0,
        0.0 if body is None else float(body),
        imp.speed,
        rtol,
        MAX_STEPS,
    )  # floats all (pydantic and Impact make them so): numba compiles one signature
    if out[3] != _STATUS_OK:  # a later contact to follow, or a failure: the general path's ending
        return _finish(imp, rtol, out[0], out[1], out[2], out[3], np.array(out[4:]))
    return _single_contact(out, rtol)


_new_object = object.__new__


_FIELDS = {  # CollisionResult's fields in their order, with a one-contact kernel solve's constants
    "cor": 0.0,
    "contact_time_s": 0.0,
    "ball_exit_velocity": 0.0,
    "final_state": (),
    "nfev": 0,
    "method": "rig-DOP853",
    "rtol": 0.0,
    "energy": None,
    "contacts": 1,
}


def _single_contact(out: tuple[Any, ...], rtol: float) -> CollisionResult:
    """The CollisionResult of a one-contact kernel solve (`_dop853.solve_impact`'s tuple out: cor,
    contact time, nfev, status, state), equal to CollisionResult(bounded_cor(cor), contact time,
    state[1], state, nfev, "rig-DOP853", rtol, {}, 1) field for field, built without the frozen
    dataclass's __init__ (one object.__setattr__ a field: 1.4 us of a ~17 us solve, here ~0.5 us):
    the fields copied from a template in their order, then set; bounded_cor's clip written out
    (its min and max calls took 0.25 us)."""
    cor = out[0]
    result = _new_object(CollisionResult)
    fields = result.__dict__
    fields.update(_FIELDS)
    fields["cor"] = cor if -1.0 <= cor <= 1.0 else (1.0 if cor > 1.0 else -1.0)  # bounded_cor (NaN: -1.0)
    fields["contact_time_s"] = out[1]
    fields["ball_exit_velocity"] = out[5]
    fields["final_state"] = out[4:]
    fields["nfev"] = out[2]
    fields["rtol"] = rtol
    fields["energy"] = {}
    return result


def _interpreted_solve(imp: Impact, rtol: float, module: ModuleType) -> CollisionResult | None:
    """`solve_general` through the interpreted kernel, None if it takes more than
    INTERPRETED_MAX_STEPS (the compiled kernel then solves it from the start: the same numbers)."""
    limit = min(INTERPRETED_MAX_STEPS, MAX_STEPS)
    cor, tc, nfev, status, state = _solve_one(imp, rtol, module, limit)
    if status == kernel.STATUS_MAX_STEPS and limit < MAX_STEPS:
        return None
    return _finish(imp, rtol, cor, tc, nfev, status, state)


def _solve_one(
    imp: Impact, rtol: float, module: ModuleType, max_steps: int, series: int = 0
) -> tuple[float, float, int, int, np.ndarray]:
    """`module`'s solve_one with the parameter vector and limits made in Python: (cor, contact
    time, nfev, status, the state at the separation)."""
    state = np.zeros(6)
    scale = imp.params.compression_scale(imp.speed)
    limit = _time_limit(imp, scale)
    cor, tc, nfev, _, status = module.solve_one(
        kernel_params(imp), imp.speed, scale, rtol, imp.n_states, limit, max_steps, state, series
    )
    return cor, tc, nfev, status, state


def check_series(series: int) -> int:
    """The series order asked for: 0 (none) or 4 to the kernel's SERIES_MAX_ORDER terms."""
    top = kernel.SERIES_MAX_ORDER
    if not (isinstance(series, int | np.integer) and (series == 0 or 4 <= series <= top)):
        raise ParameterError("series", series, f"must be 0 (DOP853 throughout) or 4 to {top} terms")
    return int(series)


def solve_general(imp: Impact, rtol: float, module: ModuleType, series: int = 0) -> CollisionResult:
    """`solve` through `module`'s solve_one (the interpreted or the compiled kernel), with the
    parameter vector and limits made in Python: the path `solve`'s lean compiled entry must equal.
    `series` as solve_one's: the contact's body in Taylor series steps of that order (0: none)."""
    rtol = check_tolerance(rtol)
    series = check_series(series)
    result = _finish(imp, rtol, *_solve_one(imp, rtol, module, MAX_STEPS, series))
    if series:
        return dataclasses.replace(result, method=result.method.replace("rig-DOP853", "rig-DOP853+series"))
    return result


def solve_series(imp: Impact, rtol: float = DEFAULT_RTOL, order: int = SERIES_ORDER) -> CollisionResult:
    """One collision by the compiled kernel with the contact's body in Taylor series steps, as the
    efficiency curve solves it (`curve.cor_grid`)."""
    return solve_general(imp, rtol, compiled(), order)


def _finish(
    imp: Impact, rtol: float, cor: float, tc: float, nfev: int, status: int, state: np.ndarray
) -> CollisionResult:
    """The result of a kernel solve: later contacts followed by the reference, failures raised."""
    contacts = 1
    if status == kernel.STATUS_FOLLOW:
        tc, last, contacts, more = continue_contacts(imp, tc, state, rtol)
        state[: imp.n_states] = last
        cor = -last[1] / imp.speed
        nfev += more
    elif status != kernel.STATUS_OK:
        raise SolverError(f"{_STATUS_TEXT.get(status, 'unknown failure')} at {_describe(imp, rtol)}")
    return CollisionResult(  # positional: a keyword call of the frozen dataclass costs twice as long
        bounded_cor(float(cor)),  # cor
        float(tc),  # contact_time_s
        float(state[1]),  # ball_exit_velocity
        tuple((state[: imp.n_states] if contacts > 1 else state).tolist()),  # final_state
        int(nfev),  # nfev
        "rig-DOP853" if contacts == 1 else "rig-DOP853+scipy-DOP853",  # method
        rtol,  # rtol
        {},  # energy
        int(contacts),  # contacts
    )


def solve_batch(
    impacts: Sequence[Impact], rtol: float = DEFAULT_RTOL, numpy_lanes: bool = False, series: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Solve many collisions in parallel; returns arrays (cor, contact_time_s).

    numpy_lanes: a batch of at most NUMPY_LANES runs in numpy unless the compiled kernel is loaded.
    series: the contact's body in Taylor series steps of that order, as `curve.cor_grid` (0: none).
    """
    rtol = check_tolerance(rtol)
    n = len(impacts)
    P = np.empty((n, kernel.N_PARAMS))
    v0 = np.empty(n)
    length = np.empty(n)
    n_active = np.empty(n, dtype=np.int64)
    t_max = np.empty(n)
    for k, imp in enumerate(impacts):
        P[k] = kernel_params(imp)
        v0[k] = imp.speed
        length[k] = imp.params.compression_scale(imp.speed)
        n_active[k] = imp.n_states
        t_max[k] = _time_limit(imp)
    return _run_batch(P, v0, length, rtol, n_active, t_max, impacts, numpy_lanes=numpy_lanes, series=series)


def _batch_kernel(n: int, numpy_lanes: bool) -> Any:
    """solve_many of the numpy lanes (a small batch that asks for them, numba not loaded) or compiled."""
    if numpy_lanes and n <= NUMPY_LANES and _COMPILED not in sys.modules:
        from rig.physics import _lanes

        return _lanes.solve_many
    return compiled().solve_many


class ImpactLookup(Protocol):
    """The impact of lane k (a Sequence[Impact], or one built only when an error message needs it)."""

    def __getitem__(self, k: int, /) -> Impact: ...


def _run_batch(
    P: np.ndarray,
    v0: np.ndarray,
    length: np.ndarray,
    rtol: float,
    n_active: np.ndarray,
    t_max: np.ndarray,
    impacts: ImpactLookup,
    contacts: np.ndarray | None = None,
    numpy_lanes: bool = False,
    evaluations: np.ndarray | None = None,
    series: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Run the lanes; lanes whose ball may meet the barrel again are followed by the reference.

    `contacts`, if given, receives each lane's number of contacts, `evaluations` its right-hand side
    evaluations; `numpy_lanes` as solve_batch's; `series` as the kernel's solve_one's (the compiled
    kernel only: the numpy lanes take DOP853 steps throughout).
    """
    series = check_series(series)
    n = P.shape[0]
    cor = np.empty(n)
    tc = np.empty(n)
    nfev = np.empty(n, dtype=np.int64)
    status = np.empty(n, dtype=np.int64)
    states = np.zeros((n, 6))
    _batch_kernel(n, numpy_lanes and not series)(
        P, v0, length, rtol, n_active, t_max, MAX_STEPS, cor, tc, nfev, status, states, series
    )
    if contacts is not None:
        contacts[:] = 1
    if evaluations is not None:
        evaluations[:] = nfev
    for k in np.flatnonzero(status == kernel.STATUS_FOLLOW):
        imp = impacts[int(k)]
        tc[k], last, count, more = continue_contacts(imp, float(tc[k]), states[k], rtol)
        cor[k] = -last[1] / imp.speed
        status[k] = kernel.STATUS_OK
        if contacts is not None:
            contacts[k] = count
        if evaluations is not None:
            evaluations[k] += more
    np.clip(cor, -1.0, 1.0, out=cor)  # |COR| <= 1 (reference.bounded_cor)
    bad = np.flatnonzero(status != kernel.STATUS_OK)
    if bad.size:
        first = int(bad[0])
        raise SolverError(
            f"{_STATUS_TEXT.get(int(status[first]), 'unknown failure')} at {_describe(impacts[first], rtol)}"
            f" ({bad.size} of {n} solves failed)"
        )
    return cor, tc


def warm_up() -> None:
    """Load (or compile) the kernel so that timed calls measure only the solving."""
    from rig.physics.params import DEFAULT_PARAMS

    compiled()
    imp = Impact(DEFAULT_PARAMS, 60.8, 1250.0)
    solve(imp, rtol=1e-6)
    solve_batch([imp], rtol=1e-6)
    solve_series(imp, rtol=1e-6)  # the curve's series path
    solve_batch([imp], rtol=1e-6, series=SERIES_ORDER)
