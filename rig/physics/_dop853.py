"""Compiled Dormand-Prince 8(5,3) kernel for the collision model (numba, cached on disk).

The same method as scipy's DOP853 (its coefficient tables are read from scipy, not copied; see
`_scipy_tables`, which does so without loading the rest of scipy.integrate), written as
scalar loops over a fixed 6-state system (the stage sums in vectors: `_vector_sums`) so that one
solve costs tens of microseconds:
- per-component absolute tolerance rtol * scale (compression scale for positions, v0 for speeds);
- contact ends where g = F/|d|^b falls through zero, located on the 7th-order dense output;
- status codes instead of exceptions (the Python wrapper turns them into SolverError).

The model it integrates (right-hand sides, g, the re-contact bounds, over the parameter vector P
and the states x1, v1, x2, v2, x3, v3) is `_kernel_model`'s, compiled inline here; this module is
the method. Loaded again as the interpreted kernel (`_interpreted`), it runs those same functions.

Why one module of ~1000 lines: it is one algorithm (step, dense output, end-of-contact location,
re-contact search, driver loop) sharing the coefficient tables, the state layout and the status
codes; split, each part would need all of them and be read without the others.
"""

from __future__ import annotations

import importlib.util
import math
import os
import sys
from pathlib import Path
from types import ModuleType

# numba's OpenMP layer spins by default between parallel regions, which cost ~8 ms a call when
# another process shares the CPUs; passive waiting costs microseconds. Set before numba loads it.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numpy as np

from rig.physics import _kernel_model as model
from rig.physics._jit import check_digest, numba_or_plain

nb = numba_or_plain(__name__)  # numba here; plain Python when loaded as the interpreted kernel

_TABLES = "scipy.integrate._ivp.dop853_coefficients"


def _scipy_tables() -> ModuleType:
    """scipy's DOP853 coefficient module, executed from its file: importing it by name would run
    scipy.integrate's __init__, about half a second of modules no kernel solve uses."""
    if _TABLES in sys.modules:
        return sys.modules[_TABLES]
    scipy = importlib.util.find_spec("scipy")  # finds the package without importing it
    if scipy is None or not scipy.submodule_search_locations:
        raise ImportError("scipy is not installed")
    path = Path(next(iter(scipy.submodule_search_locations)), "integrate", "_ivp", "dop853_coefficients.py")
    spec = importlib.util.spec_from_file_location("_rig_dop853_tables", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot read scipy's DOP853 tables from {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_coef = _scipy_tables()

_A = np.ascontiguousarray(_coef.A, dtype=np.float64)
_B = np.ascontiguousarray(_coef.B, dtype=np.float64)
_C = np.ascontiguousarray(_coef.C, dtype=np.float64)
_E3 = np.ascontiguousarray(_coef.E3, dtype=np.float64)
_E5 = np.ascontiguousarray(_coef.E5, dtype=np.float64)
_D = np.ascontiguousarray(_coef.D, dtype=np.float64)
_NS = 12  # stages of the step proper
_NX = 16  # stages including those of the dense output


def _sparse_rows(table: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A table's nonzero entries row by row, in column order: (row starts, columns, values).

    The stage sums run over these only: a skipped term is 0 * K, which changes no finite sum, and
    the terms kept are added in the same order, so the sums are the same to the last bit.
    """
    rows = np.atleast_2d(table)
    starts = np.zeros(rows.shape[0] + 1, dtype=np.int64)
    columns: list[int] = []
    for r in range(rows.shape[0]):
        columns += [int(j) for j in np.flatnonzero(rows[r])]
        starts[r + 1] = len(columns)
    cols = np.array(columns, dtype=np.int64)
    return (
        starts,
        cols,
        np.ascontiguousarray(rows[np.repeat(np.arange(rows.shape[0]), np.diff(starts)), cols]),
    )


_A_START, _A_COL, _A_VAL = _sparse_rows(_A)
_, _B_COL, _B_VAL = _sparse_rows(_B[:_NS])
_D_START, _D_COL, _D_VAL = _sparse_rows(_D)
_E_COL = np.flatnonzero((_E5[: _NS + 1] != 0.0) | (_E3[: _NS + 1] != 0.0)).astype(np.int64)
_E5_VAL = np.ascontiguousarray(_E5[_E_COL])
_E3_VAL = np.ascontiguousarray(_E3[_E_COL])

N_PARAMS = 11
STATUS_OK = 0
STATUS_TIME_LIMIT = 1
STATUS_MAX_STEPS = 2
STATUS_STEP_UNDERFLOW = 3
STATUS_NOT_FINITE = 4
STATUS_FOLLOW = 5  # first contact solved; the ball may meet the barrel again: the caller follows on

SCREEN_POINTS = 256  # samples of free flight per barrel period (and per escape window)
SCREEN_MAX_SAMPLES = 200_000

_SAFETY = 0.9
_MIN_FACTOR = 0.2
_MAX_FACTOR = 10.0
_EXPONENT = -1.0 / 8.0

# The body of a contact in Taylor series steps (`solve_one(..., series=order)`): see `_series_contact`.
SERIES_START = 0.2  # series take over after this many time scales (length / v0) of DOP853 steps
_SERIES_SAFETY = 0.96  # about exp(-0.7 / (order - 1)) for 16-20 terms (Jorba and Zou 2005, Sect. 3.2)
_G_ROW = model._G  # the rows of g and d in the series' aux
_D_ROW = model._D
SERIES_SAMPLES = 64  # points at which a step's g polynomial is read for a dip below zero
SERIES_MAX_ORDER = 17  # g's polynomial (degree order - 1) stays below SERIES_SAMPLES / 4
_SERIES_APPROACH = 0.1  # DOP853's steps after a hand-back: at most this share of the time to d = 0
SERIES_END_CLEARANCE = 0.05  # series only where the contact ends this many scales clear of d = 0
_SERIES_SHRINK = 0.25  # a step this much shorter than the longest: a branch point ahead, DOP853 goes on
SERIES_SEPARATED = 0
SERIES_HANDBACK = 1

# The model (right-hand sides, g and its rate, the damping rate, the re-contact bounds): one
# definition in _kernel_model, compiled here inline into the loops (no call overhead); in the
# interpreted kernel `_inline` gives each function back unchanged.
_inline = nb.njit(cache=True, inline="always")
_rhs = _inline(model.rhs)
_rhs_free = _inline(model.rhs_free)
_gfun = _inline(model.gfun)
_gdot = _inline(model.gdot)
_g_and_rate = _inline(model.g_and_rate)
_g_clear = _inline(model.g_clear)
_damping_rate = _inline(model.damping_rate)
g_cannot_rise = _inline(model.g_cannot_rise)
_force_escape_time = _inline(model.force_escape_time)
_series = _inline(model.series)
_series_damped = _inline(model.series_damped)

# numba's cache of this module's functions is keyed on this file's text alone, not on the
# _kernel_model they inline: that file's text is pinned here, so an edit there must change this
# line too, which renews the cache (the kernel refuses to load until then).
MODEL_DIGEST = "6831aa9e4053091286fed655f457a7818b4dd8e2da796770db696759c13dc721"
check_digest(model, MODEL_DIGEST, Path(__file__).name)


@nb.njit(cache=True)
def _dense(
    y: np.ndarray,
    ynew: np.ndarray,
    f: np.ndarray,
    fnew: np.ndarray,
    h: float,
    p: np.ndarray,
    K: np.ndarray,
    tmp: np.ndarray,
    F: np.ndarray,
) -> None:
    """Coefficients of the 7th-order dense output of the step just taken (scipy's DOP853 form)."""
    n = _moving(p)
    _stages(y, h, p, K, tmp, _NS + 1, _NX, n)
    for i in range(n):
        dy = ynew[i] - y[i]
        F[0, i] = dy
        F[1, i] = h * f[i] - dy
        F[2, i] = 2.0 * dy - h * (fnew[i] + f[i])
    for r in range(4):
        sums = _combine(K, _D_COL, _D_VAL, _D_START[r], _D_START[r + 1], n)
        for i in range(n):
            F[3 + r, i] = h * sums[i]


@nb.njit(cache=True, inline="always")
def _g_at(
    x: float,
    y: np.ndarray,
    F: np.ndarray,
    S: np.ndarray,
    h: float,
    order: int,
    p: np.ndarray,
    tmp: np.ndarray,
) -> float:
    """g at the fraction x of the step: on its 7th-order dense output (y, F; order 0) or on the
    series' polynomials (S, of that order, over the step's length h); tmp receives the state."""
    n = _moving(p)
    if order == 0:
        _interpolate(y, F, x, tmp, n)
    else:
        for i in range(n):
            tmp[i] = _horner(S, i, order, x * h)
    return _gfun(tmp, p)


@nb.njit(cache=True, inline="always")
def _difference_range(y: np.ndarray, F: np.ndarray, i: int, j: int) -> tuple:
    """(least, greatest, size) of state i - state j over the step's dense output, bounded through
    its nested form y + x (F0 + (1 - x) (F1 + x (F2 + ...))): each factor x or 1 - x lies in
    [0, 1]; size: the sum of the magnitudes the difference is computed from."""
    lo = 0.0
    hi = 0.0
    size = abs(y[i]) + abs(y[j])
    for k in range(6, -1, -1):
        c = F[k, i] - F[k, j]
        lo = min(0.0, lo + c)
        hi = max(0.0, hi + c)
        size += abs(F[k, i]) + abs(F[k, j])
    base = y[i] - y[j]
    return base + lo, base + hi, size


@nb.njit(cache=True)
def _dense_clear(y: np.ndarray, F: np.ndarray, p: np.ndarray) -> bool:
    """True when no point of the step's dense output has g <= 0, shown from the ranges of d and d'
    on it (`_difference_range`, `_kernel_model.g_clear`): no dip of the step can reach zero, and
    the search for one (`_minimum`), which would find none, is not needed (g can be NaN there,
    0 * inf with k1 = 0 and a subnormal d, which is not <= 0 either)."""
    d_lo, _, d_size = _difference_range(y, F, 0, 2)
    v_lo, _, v_size = _difference_range(y, F, 1, 3)
    return _g_clear(d_lo, d_size, v_lo, v_size, p)


@nb.njit(cache=True)
def dip_width(rtol: float) -> float:
    """The bracket (a fraction of the step) at which `_minimum` stops: sqrt(rtol), at most 1e-3.

    Within a bracket w wide of the minimum, g exceeds its least value by at most max|g''| (w h)^2 / 2
    (tests/physics/test_dip_width.py holds the search to that): a dip the search stops short of is
    shallower than rtol / 2 of g's swing over the step where g'' h^2 is about that swing, below what
    the dense output holds g to (a rule of thumb: on a 7th-degree dense output |g''| h^2 can be
    hundreds of swings). A point at or below zero ends the search at once, whatever w. An outside
    review found results parting from the 1e-12 search's only on knife edges (parameter bands of
    1e-8 to 1e-13 relative, against the 1e-6 by which rtol alone moves them), where the 1e-12 search
    had found a separation that tighter tolerances and scipy do not."""
    return min(1e-3, math.sqrt(rtol))


@nb.njit(cache=True)
def _minimum(y: np.ndarray, F: np.ndarray, p: np.ndarray, tmp: np.ndarray, width: float) -> tuple:
    """Golden-section search for the minimum of g on the step's dense output, to a bracket `width`
    wide (`dip_width`), or to the first point where g <= 0: (x, g)."""
    n = _moving(p)
    invphi = 0.6180339887498949
    a = 0.0
    b = 1.0
    c = b - invphi * (b - a)
    d = a + invphi * (b - a)
    _interpolate(y, F, c, tmp, n)
    gc = _gfun(tmp, p)
    _interpolate(y, F, d, tmp, n)
    gd = _gfun(tmp, p)
    for _ in range(60):
        if gc <= 0.0:
            return c, gc
        if gd <= 0.0 and gc > gd:
            return d, gd
        if gc < gd:
            b = d
            d = c
            gd = gc
            c = b - invphi * (b - a)
            _interpolate(y, F, c, tmp, n)
            gc = _gfun(tmp, p)
        else:
            a = c
            c = d
            gc = gd
            d = a + invphi * (b - a)
            _interpolate(y, F, d, tmp, n)
            gd = _gfun(tmp, p)
        if b - a < width:
            break
    if gc < gd:
        return c, gc
    return d, gd


@nb.njit(cache=True, inline="always")
def _g_swing(aux: np.ndarray, degree: int, h: float) -> float:
    """sum over 1 <= k <= degree of |G_k| h^k: g's polynomial stays above zero over the step where
    this is below its value at the start (the cheapest test, tried first)."""
    acc = 0.0
    for k in range(degree, 0, -1):
        acc = (acc + abs(aux[_G_ROW, k])) * h
    return acc


def _bernstein_weights(top: int) -> np.ndarray:
    """W[m, i, k] = C(i, k) / C(m, k): a polynomial sum_k a_k x^k of degree m has the Bernstein
    coefficients b_i = sum_(k <= i) W[m, i, k] a_k on [0, 1]."""
    w = np.zeros((top + 1, top + 1, top + 1))
    for m in range(top + 1):
        for i in range(m + 1):
            for k in range(i + 1):
                w[m, i, k] = math.comb(i, k) / math.comb(m, k)
    return w


@nb.njit(cache=True)
def _g_stays_up(aux: np.ndarray, degree: int, h: float) -> bool:
    """True when g's polynomial of `degree` is above zero over the whole step of length h: every
    coefficient of it in the Bernstein basis on the step is (the polynomial lies in their convex
    hull). False says only that it might not be."""
    for i in range(degree + 1):
        b = 0.0
        hk = 1.0
        for k in range(i + 1):
            b += _BERNSTEIN[degree, i, k] * aux[_G_ROW, k] * hk
            hk *= h
        if b <= 0.0:
            return False
    return True


@nb.njit(cache=True)
def _series_first_down(aux: np.ndarray, degree: int, h: float) -> float:
    """The first of SERIES_SAMPLES evenly spaced fractions of the step where g's own polynomial is at
    or below zero (2.0 if none): a polynomial of degree `degree` < SERIES_SAMPLES / 4 has no dip
    narrower than the spacing."""
    for k in range(1, SERIES_SAMPLES + 1):
        x = k / SERIES_SAMPLES
        if _horner(aux, _G_ROW, degree, x * h) <= 0.0:
            return x
    return 2.0


@nb.njit(cache=True)
def _crossing(
    y: np.ndarray,
    F: np.ndarray,
    S: np.ndarray,
    h: float,
    order: int,
    p: np.ndarray,
    tmp: np.ndarray,
    glo: float,
    hi: float,
    ghi: float,
) -> float:
    """Where g falls through zero in (0, hi] (fractions of the step; g(0) = glo > 0 >= g(hi) = ghi),
    as `_g_at` reads it: Illinois."""
    lo = 0.0
    side = 0
    x = hi
    for _ in range(100):
        x = (lo * ghi - hi * glo) / (ghi - glo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        gx = _g_at(x, y, F, S, h, order, p, tmp)
        if gx > 0.0:
            lo = x
            glo = gx
            if side == 1:
                ghi *= 0.5
            side = 1
        else:
            hi = x
            ghi = gx
            if side == -1:
                glo *= 0.5
            side = -1
        if hi - lo <= 4e-16 * max(1.0, hi) or gx == 0.0:
            break
    return hi


@nb.njit(cache=True, inline="always")
def _moving(p: np.ndarray) -> int:
    """The states that move (the others stay 0 and are left out of every sum): all six with a body;
    ball and barrel on a clamped flexible barrel; the ball alone on a clamped rigid one."""
    if p[8] != 0.0:
        return 6
    if p[10] != 0.0:
        return 2
    return 4


@nb.njit(cache=True, inline="always")
def _combine(K: np.ndarray, cols: np.ndarray, vals: np.ndarray, lo: int, hi: int, n: int) -> tuple:
    """sum over q in lo..hi-1 of vals[q] * K[cols[q]], for the `n` moving states (0 for the others).

    Each state's terms are added in the same order as a plain loop would; the states' sums run side
    by side in registers, so the additions of one state wait for one another only, not for all."""
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    for q in range(lo, hi):
        c = vals[q]
        j = cols[q]
        s0 += c * K[j, 0]
        s1 += c * K[j, 1]
        if n > 2:
            s2 += c * K[j, 2]
            s3 += c * K[j, 3]
            if n > 4:
                s4 += c * K[j, 4]
                s5 += c * K[j, 5]
    return s0, s1, s2, s3, s4, s5


@nb.njit(cache=True, inline="always")
def _step_sums(K: np.ndarray, n: int) -> tuple:
    """The step's three sums over its stages: the solution's (B) and the two error estimates' (E5,
    E3), each as `_combine`'s."""
    return (
        _combine(K, _B_COL, _B_VAL, 0, _B_COL.size, n),
        _combine(K, _E_COL, _E5_VAL, 0, _E_COL.size, n),
        _combine(K, _E_COL, _E3_VAL, 0, _E_COL.size, n),
    )


if hasattr(nb, "__version__"):  # numba: the compiled kernel's sums, in vectors
    from llvmlite import ir  # type: ignore[import-untyped]
    from numba import types
    from numba.core import cgutils
    from numba.core.errors import TypingError
    from numba.extending import intrinsic

    if not (np.array_equal(_B_COL, _E_COL) and _NS not in _E_COL):
        raise ImportError(
            "DOP853's tables: B and E no longer share their stages; _vector_sums3 needs them to"
        )

    def _sums_codegen(m: int):
        """LLVM IR of `m` of `_combine`'s sums over one table's columns (m tables of values): each
        term's first four states as one vector of four, the last two (n > 4) as one of two, the
        same products added in the same order lane by lane, so the same numbers to the last bit.
        The last term, the stage written last, is read and added in scalars: a vector load of
        what scalar stores have just written waits until they reach the cache. The first four
        states are summed for every n: a state that does not move has K = +-0 there, and
        y + h * (+-0) leaves its 0 as it was. Needs hi > lo."""

        def codegen(context, builder, signature, args):
            k_arg, cols_arg, *val_args, lo_arg, hi_arg, n_arg = args
            k_ty, cols_ty, *val_tys, lo_ty, hi_ty, n_ty = signature.args
            karr = context.make_array(k_ty)(context, builder, k_arg)
            carr = context.make_array(cols_ty)(context, builder, cols_arg)
            varrs = [
                context.make_array(t)(context, builder, v) for t, v in zip(val_tys, val_args, strict=True)
            ]
            start = context.cast(builder, lo_arg, lo_ty, types.intp)
            last = builder.sub(context.cast(builder, hi_arg, hi_ty, types.intp), start.type(1))
            wide = builder.icmp_signed(">", context.cast(builder, n_arg, n_ty, types.intp), start.type(4))
            f64, i32 = ir.DoubleType(), ir.IntType(32)
            v4, v2 = ir.VectorType(f64, 4), ir.VectorType(f64, 2)
            acc4 = [cgutils.alloca_once_value(builder, ir.Constant(v4, [0.0] * 4)) for _ in range(m)]
            acc2 = [cgutils.alloca_once_value(builder, ir.Constant(v2, [0.0] * 2)) for _ in range(m)]
            shape = cgutils.unpack_tuple(builder, karr.shape)
            strides = cgutils.unpack_tuple(builder, karr.strides)

            def row(q):
                j = builder.load(cgutils.gep(builder, carr.data, q))
                return cgutils.get_item_pointer2(
                    context, builder, karr.data, shape, strides, "C", [j, start.type(0)]
                )

            def splat(c, vector):
                out = ir.Constant(vector, ir.Undefined)
                for lane in range(vector.count):
                    out = builder.insert_element(out, c, i32(lane))
                return out

            with cgutils.for_range_slice(builder, start, last, start.type(1)) as (q, _):
                at = row(q)
                coefficients = [builder.load(cgutils.gep(builder, v.data, q)) for v in varrs]
                four = builder.load(builder.bitcast(at, v4.as_pointer()), align=8)
                for c, acc in zip(coefficients, acc4, strict=True):
                    builder.store(builder.fadd(builder.load(acc), builder.fmul(splat(c, v4), four)), acc)
                with builder.if_then(wide):
                    two = builder.load(builder.bitcast(cgutils.gep(builder, at, 4), v2.as_pointer()), align=8)
                    for c, acc in zip(coefficients, acc2, strict=True):
                        builder.store(builder.fadd(builder.load(acc), builder.fmul(splat(c, v2), two)), acc)
            at = row(last)
            terms = [builder.load(cgutils.gep(builder, at, i)) for i in range(6)]
            sums = []
            for v, a4, a2 in zip(varrs, acc4, acc2, strict=True):
                c = builder.load(cgutils.gep(builder, v.data, last))
                four, two = builder.load(a4), builder.load(a2)
                lanes = [builder.extract_element(four, i32(i)) for i in range(4)]
                lanes += [builder.extract_element(two, i32(i)) for i in range(2)]
                for i in range(6):
                    total = builder.fadd(lanes[i], builder.fmul(c, terms[i]))
                    sums.append(total if i < 4 else builder.select(wide, total, lanes[i]))
            return context.make_tuple(builder, signature.return_type, sums)

        return codegen

    def _check_layout(K, cols, *vals):
        """The codegen reads K as C-ordered rows of float64 and the table as C-ordered arrays: any
        other layout is refused when the caller is compiled (its row count of 6 is checked at run
        time, by `_combine` and `_step_sums`)."""

        def c_array(t, dtype, ndim):
            return isinstance(t, types.Array) and t.dtype == dtype and t.ndim == ndim and t.layout == "C"

        if not (
            c_array(K, types.float64, 2)
            and c_array(cols, types.int64, 1)
            and all(c_array(v, types.float64, 1) for v in vals)
        ):
            raise TypingError(f"_vector_sums needs C-ordered float64 K (2-d), int64 columns: got {K}, {cols}")

    @intrinsic
    def _vector_sums(typingctx, K, cols, vals, lo, hi, n):
        """`_combine`'s sums (`_sums_codegen`, one table of values)."""
        _check_layout(K, cols, vals)
        return types.UniTuple(types.float64, 6)(K, cols, vals, lo, hi, n), _sums_codegen(1)

    @intrinsic
    def _vector_sums3(typingctx, K, cols, v1, v2, v3, lo, hi, n):
        """Three of `_combine`'s sums over the same columns, in one pass (`_sums_codegen`)."""
        _check_layout(K, cols, v1, v2, v3)
        return types.UniTuple(types.float64, 18)(K, cols, v1, v2, v3, lo, hi, n), _sums_codegen(3)

    @nb.njit(cache=True, inline="always")
    def _combine(K: np.ndarray, cols: np.ndarray, vals: np.ndarray, lo: int, hi: int, n: int) -> tuple:
        """`_combine` above, compiled: the same sums, in vectors (`_vector_sums`)."""
        if K.shape[1] != 6:
            raise ValueError("_combine: K must have the kernel's 6 states a row")
        if hi <= lo:
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        return _vector_sums(K, cols, vals, lo, hi, n)  # type: ignore[call-arg]

    @nb.njit(cache=True, inline="always")
    def _step_sums(K: np.ndarray, n: int) -> tuple:
        """`_step_sums` above, compiled: the three sums in one pass over the stages (`_vector_sums3`)."""
        if K.shape[1] != 6:
            raise ValueError("_step_sums: K must have the kernel's 6 states a row")
        r: tuple[float, ...] = _vector_sums3(K, _B_COL, _B_VAL, _E5_VAL, _E3_VAL, 0, _B_COL.size, n)  # type: ignore[call-arg]
        return (
            (r[0], r[1], r[2], r[3], r[4], r[5]),
            (r[6], r[7], r[8], r[9], r[10], r[11]),
            (r[12], r[13], r[14], r[15], r[16], r[17]),
        )


@nb.njit(cache=True, inline="always")
def _advance(y: np.ndarray, h: float, sums: tuple, out: np.ndarray) -> None:
    """out = y + h * sums, state by state."""
    out[0] = y[0] + h * sums[0]
    out[1] = y[1] + h * sums[1]
    out[2] = y[2] + h * sums[2]
    out[3] = y[3] + h * sums[3]
    out[4] = y[4] + h * sums[4]
    out[5] = y[5] + h * sums[5]


@nb.njit(cache=True)
def _stages(
    y: np.ndarray, h: float, p: np.ndarray, K: np.ndarray, tmp: np.ndarray, first: int, last: int, n: int
) -> None:
    """Stages first..last-1: each one's state from the earlier stages (the table's nonzero terms,
    the `n` moving states), then the right-hand side there."""
    for s in range(first, last):
        _advance(y, h, _combine(K, _A_COL, _A_VAL, _A_START[s], _A_START[s + 1], n), tmp)
        _rhs(tmp, p, K[s])


@nb.njit(cache=True)
def _interpolate(y: np.ndarray, F: np.ndarray, x: float, out: np.ndarray, n: int) -> None:
    for i in range(n):
        acc = 0.0
        for k in range(6, -1, -1):
            acc += F[k, i]
            if (6 - k) % 2 == 0:
                acc *= x
            else:
                acc *= 1.0 - x
        out[i] = y[i] + acc


@nb.njit(cache=True, inline="always")
def _horner(M: np.ndarray, i: int, degree: int, x: float) -> float:
    """sum over k <= degree of M[i, k] x^k (row i indexed, not sliced: a view costs two atomic
    reference counts)."""
    acc = M[i, degree]
    for k in range(degree - 1, -1, -1):
        acc = acc * x + M[i, k]
    return acc


@nb.njit(cache=True)
def _series_step(
    S: np.ndarray,
    aux: np.ndarray,
    y: np.ndarray,
    rtol: float,
    atol: np.ndarray,
    g_tol: float,
    n: int,
    order: int,
) -> float:
    """The step whose last two terms are each within the tolerance (Jorba and Zou's rule), for every
    moving state and for g: h = safety * min over q = order - 1, order of (max_i |S[i, q]| / tol_i)^(-1/q).

    g's last term counts too (its polynomial is of degree order - 1; tolerance g_tol): the contact's
    end is found on its polynomial, and g (a power of d) can branch at d = 0 where the states do not
    (a ball without damping, whose force is linear, leaves at d = 0): the step stays short of it."""
    r1 = abs(aux[_G_ROW, order - 1]) / g_tol
    r2 = 0.0
    for i in range(n):
        tol = atol[i] + rtol * abs(y[i])
        r1 = max(r1, abs(S[i, order - 1]) / tol)
        r2 = max(r2, abs(S[i, order]) / tol)
    h = math.inf
    if r1 > 0.0:
        h = r1 ** (-1.0 / (order - 1))
    if r2 > 0.0:
        h = min(h, r2 ** (-1.0 / order))
    return _SERIES_SAFETY * h


_BERNSTEIN = _bernstein_weights(SERIES_MAX_ORDER)


@nb.njit(cache=True)
def _series_contact(
    y: np.ndarray,
    t: float,
    p: np.ndarray,
    rtol: float,
    atol: np.ndarray,
    n: int,
    order: int,
    t_max: float,
    steps_left: int,
) -> tuple:
    """The contact from y (at time t, g > 0) in Taylor series steps, to its end or to a point where
    DOP853 must go on: (SERIES_SEPARATED or SERIES_HANDBACK, t, steps, the longest first step for
    DOP853); y is left at the separation or where the series stopped (time limit and step budget:
    the caller's checks see them).

    Away from d = 0 the solution is analytic, and a series of `order` terms steps over several
    barrel periods where DOP853 takes about five steps a period. Each step's series is its own dense
    output: the contact ends where g of the states' polynomials falls through zero, also inside the
    step (a brief separation between two positive ends, or a first of two crossings), looked for
    where g's own polynomial is not proved positive over the step (`_g_swing`, `_g_stays_up`). It
    hands back when d <= 0 is near (d reaches 0 within a step, or the steps shrink towards that
    branch point), where the ball's damping outruns the contact's own oscillation (`_series_damped`:
    an over-damped ball creeps off with g hugging zero, and whether and where g crosses is decided at
    the tolerance's level: DOP853 keeps its steps short there), or where a number is not finite.
    """
    S = np.empty((6, order + 1))
    aux = np.empty((7, order + 1))
    tmp = np.zeros(6)
    steps = 0
    h_most = 0.0  # the longest step so far
    h_next = math.inf  # the first step DOP853 may take after a hand-back
    # g's absolute tolerance: rtol times its scale, k1 length^(1+a-b) + c1 v0 (atol = rtol * scale)
    g_atol = atol[0] * p[1] * (atol[0] / rtol) ** (p[3] - p[4]) + atol[1] * p[2]
    while steps < steps_left and t < t_max:
        if not _series(y, p, order, S, aux) or _series_damped(aux, p):
            break
        g_tol = g_atol + rtol * abs(aux[_G_ROW, 0])
        h = min(_series_step(S, aux, y, rtol, atol, g_tol, n, order), t_max - t)
        d0 = y[0] - y[2]
        if not (h > _SERIES_SHRINK * h_most and math.isfinite(h)):
            # DOP853 goes on no longer than the series would, nor than _SERIES_APPROACH of the time
            # d takes to reach 0 at its rate: there the force's powers branch, and a step across
            # that point, which DOP853's error estimate does not see, can end the contact with many
            # times the tolerance's error; from there its own steps approach as it would have alone
            rate = aux[_D_ROW, 1]
            h_next = h if rate >= 0.0 else min(h, _SERIES_APPROACH * d0 / -rate)
            break
        g_end = _g_at(1.0, y, S, S, h, order, p, tmp)
        d_end = tmp[0] - tmp[2]
        if not math.isfinite(g_end):
            break
        if not d_end > 0.0:
            # d reaches 0 within the step: the series holds only short of that branch point (the
            # time to it from the step's ends, as above)
            h_next = _SERIES_APPROACH * h * d0 / (d0 - d_end)
            break
        steps += 1
        crossed = g_end <= 0.0
        hi = 1.0
        ghi = g_end
        if _g_swing(aux, order - 1, h) >= aux[_G_ROW, 0] and not _g_stays_up(aux, order - 1, h):
            # g's polynomial may reach zero inside the step (a dip between two positive ends, or a
            # first crossing before a later one): its first sample at or below zero bounds the end
            x = _series_first_down(aux, order - 1, h)
            if x < 1.0:
                gx = _g_at(x, y, S, S, h, order, p, tmp)
                if gx <= 0.0:
                    crossed = True
                    hi = x
                    ghi = gx
        if crossed:
            x = _crossing(y, S, S, h, order, p, tmp, _gfun(y, p), hi, ghi)
            _g_at(x, y, S, S, h, order, p, y)
            return SERIES_SEPARATED, t + x * h, steps, h
        for i in range(n):
            y[i] = _horner(S, i, order, h)
        t += h
        h_most = max(h_most, h)
    return SERIES_HANDBACK, t, steps, h_next


@nb.njit(cache=True, inline="always")
def _series_ends_clear(p: np.ndarray, v0: float, length: float) -> bool:
    """True where the contact ends clear of d = 0, the force's branch point, which no series steps
    up to: g = k1 d^(1+a-b) + c1 d' falls to zero at d ~ (c1 v0 / k1)^(1 / (1+a-b)), here at least
    SERIES_END_CLEARANCE compression scales. Not so for an undamped ball (c1 = 0: it leaves at
    d = 0), nor where the damping is a tiny part of g's scale k1 length^(1+a-b) (there DOP853
    steps across d = 0 to the end; the series path would hand back just short of it and DOP853,
    starting there, lands on the end with several times its own error)."""
    gam = 1.0 + p[3] - p[4]
    if p[2] <= 0.0 or gam <= 0.0:
        return False
    return (p[2] * v0 / (p[1] * length**gam)) ** (1.0 / gam) >= SERIES_END_CLEARANCE


@nb.njit(cache=True)
def _separated(
    state: np.ndarray,
    t: float,
    t_end: float,
    v0: float,
    p: np.ndarray,
    nfev: int,
    steps: int,
    out: np.ndarray,
) -> tuple:
    """solve_one's result at the first separation (state at time t_end; t where the last step began)."""
    for i in range(6):
        out[i] = state[i]
        if not math.isfinite(state[i]):
            return math.nan, t, nfev, steps, STATUS_NOT_FINITE
    if may_meet_again(state, p):
        return -state[1] / v0, t_end, nfev, steps, STATUS_FOLLOW
    return -state[1] / v0, t_end, nfev, steps, STATUS_OK


@nb.njit(cache=True)
def solve_one(
    p: np.ndarray,
    v0: float,
    length: float,
    rtol: float,
    n_active: int,
    t_max: float,
    max_steps: int,
    out_state: np.ndarray,
    series: int,
) -> tuple:
    """Integrate one collision; returns (cor, contact_time, nfev, steps, status).

    series: 0, DOP853 steps throughout; else the contact's body, from SERIES_START time scales on,
    in Taylor series steps of that order (`_series_contact`; steps counts theirs too), where the
    contact ends clear of d = 0 (`_series_ends_clear`)."""
    y = np.zeros(6)
    y[1] = v0
    ynew = np.zeros(6)
    f = np.zeros(6)
    fnew = np.zeros(6)
    tmp = np.zeros(6)
    K = np.zeros((_NX, 6))
    F = np.zeros((7, 6))
    atol = np.empty(6)
    for i in range(6):
        atol[i] = rtol * (length if i % 2 == 0 else v0)
    n = _moving(p)
    _rhs(y, p, f)
    nfev = 1
    kappa = min(1.0, (40320.0 * rtol) ** 0.125)
    width = dip_width(rtol)
    t_unit = length / v0
    t = 0.0
    h = 1e-4 * length / v0
    g_old = _gfun(y, p)
    gd_old = math.nan  # g's rate at y, carried from the step that ended there (nan: not known)
    rejected = False
    steps = 0
    t_series = SERIES_START * length / v0 if series > 0 and _series_ends_clear(p, v0, length) else math.inf
    approach = False  # after a hand-back: every step short of d = 0 (_SERIES_APPROACH of the way)
    while True:
        if steps >= max_steps:
            return math.nan, t, nfev, steps, STATUS_MAX_STEPS
        if t >= t_max:
            return math.nan, t, nfev, steps, STATUS_TIME_LIMIT
        if h < 1e-14 * max(t, t_unit):
            return math.nan, t, nfev, steps, STATUS_STEP_UNDERFLOW
        if approach and f[0] < f[2]:
            h = min(h, _SERIES_APPROACH * (y[0] - y[2]) / (f[2] - f[0]))
        for i in range(n):
            K[0, i] = f[i]
        _stages(y, h, p, K, tmp, 1, _NS, n)
        sums, a5, a3 = _step_sums(K, n)
        _advance(y, h, sums, ynew)
        _rhs(ynew, p, fnew)
        for i in range(n):
            K[_NS, i] = fnew[i]
        nfev += _NS
        e5 = 0.0
        e3 = 0.0
        for i in range(n):
            sc = atol[i] + rtol * max(abs(y[i]), abs(ynew[i]))
            q5 = a5[i] / sc
            q3 = a3[i] / sc
            e5 += q5 * q5  # not q ** 2: the interpreter takes that as pow(q, 2), ~1 in 1,000 a last bit off
            e3 += q3 * q3
        err = 0.0 if e5 == 0.0 and e3 == 0.0 else abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n_active)
        if not math.isfinite(err):
            h *= _MIN_FACTOR
            rejected = True
            steps += 1
            continue
        if err >= 1.0:
            h *= max(_MIN_FACTOR, _SAFETY * err**_EXPONENT)
            rejected = True
            steps += 1
            continue
        # accepted step
        steps += 1
        g_new, gd_new = _g_and_rate(ynew, fnew, p)
        crossed = g_old > 0.0 and g_new <= 0.0
        dip = False
        if not crossed and g_old > 0.0:
            if math.isnan(gd_old):
                gd_old = _gdot(y, f, p)
            dip = gd_old < 0.0 and gd_new > 0.0
        if (crossed or dip) and h * _damping_rate(y, p) > kappa:
            # contact may end inside this step, whose dense output would not resolve the decay
            # of the relative motion (rate lam): retake it short enough that it does
            h = 0.9 * kappa / _damping_rate(y, p)
            rejected = True
            continue
        if dip:
            # g has a minimum inside the step: F may dip below zero and come back between the
            # step's ends (a brief separation). Look inside on the dense output.
            _dense(y, ynew, f, fnew, h, p, K, tmp, F)
            nfev += _NX - _NS - 1
            x_min, g_min = 1.0, math.inf  # where g > 0 is shown over the whole step, no search
            if not _dense_clear(y, F, p):
                x_min, g_min = _minimum(y, F, p, tmp, width)
            if g_min <= 0.0:
                crossed = True
                g_new = g_min
                hi_start = x_min
            else:
                hi_start = 1.0
        elif crossed:
            _dense(y, ynew, f, fnew, h, p, K, tmp, F)
            nfev += _NX - _NS - 1
            hi_start = 1.0
        if crossed:
            x = _crossing(y, F, F, h, 0, p, tmp, g_old, hi_start, g_new)
            _interpolate(y, F, x, tmp, n)
            return _separated(tmp, t, t + x * h, v0, p, nfev, steps, out_state)
        factor = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, _SAFETY * err**_EXPONENT)
        if rejected:
            factor = min(1.0, factor)
        rejected = False
        t += h
        h *= factor
        g_old = g_new
        gd_old = gd_new
        for i in range(n):
            y[i] = ynew[i]
            f[i] = fnew[i]
        if t >= t_series:
            t_series = math.inf  # once a solve: after a hand-back, DOP853 goes on to the end
            code, t, used, h_next = _series_contact(y, t, p, rtol, atol, n, series, t_max, max_steps - steps)
            steps += used
            h = min(h, h_next)
            if code == SERIES_SEPARATED:
                return _separated(y, t, t, v0, p, nfev, steps, out_state)
            approach = True
            if used > 0:
                _rhs(y, p, f)
                nfev += 1
                g_old = _gfun(y, p)
                gd_old = math.nan


@nb.njit(cache=True)
def solve_impact(
    m1: float,
    k1: float,
    c1: float,
    a: float,
    b: float,
    m2: float,
    c2: float,
    hoop: float,
    body: float,
    speed: float,
    rtol: float,
    max_steps: int,
) -> tuple:
    """One collision from the impact's own numbers (hoop 0: rigid barrel; body 0: clamped), for
    `fast.solve`: the parameter vector, length scale, state count and time limit are made here, as
    `fast.kernel_params`, `CollisionParams.compression_scale` and `reference._time_limit` make them
    (the same operations, so the same numbers), instead of in Python on every call.

    Returns (cor, contact_time, nfev, status, x1, v1, x2, v2, x3, v3): the state at the separation
    as numbers, so that no array crosses into Python."""
    rigid = hoop == 0.0
    clamped = body == 0.0
    p = np.empty(N_PARAMS)
    p[0] = m1
    p[1] = k1
    p[2] = c1
    p[3] = a
    p[4] = b
    p[5] = m2
    w = 2.0 * math.pi * hoop
    p[6] = 0.0 if rigid else m2 * (w * w)  # params.barrel_spring, compiled (w * w, not pow(w, 2))
    p[7] = c2
    p[8] = 0.0 if clamped else 1.0 / body
    p[9] = 0.0 if clamped else 1.0 / (m2 + body)
    p[10] = 1.0 if rigid else 0.0
    n = 2.0 + a
    scale = (n * m1 * speed * speed / (2.0 * k1)) ** (1.0 / n)
    t_max = 500.0 * scale / speed
    if not rigid:
        t_max = t_max + 20.0 / hoop * max(1.0, math.sqrt(m1 / m2))
    n_active = 2 + (0 if rigid else 2) + (0 if clamped else 2)
    s = np.zeros(6)
    # no series: a zero typed int64, as the callers' from Python (a literal 0 would be typed apart
    # and compile the kernel a second time)
    no_series = max_steps - max_steps
    cor, tc, nfev, _, status = solve_one(p, speed, scale, rtol, n_active, t_max, max_steps, s, no_series)
    return cor, tc, nfev, status, s[0], s[1], s[2], s[3], s[4], s[5]


@nb.njit(cache=True)
def may_meet_again(y0: np.ndarray, p: np.ndarray) -> bool:
    """After a separation: False when no later contact is possible (the separation is final).

    A rigid barrel recedes at a constant speed, so once the ball is slower no contact can come.
    A flexible barrel is bounded: the ball is out of reach for good once it is beyond the
    barrel's largest excursion and slower than the barrel's centre of mass (equations.escape_time).
    Until then free flight is sampled (RK4, 256 points per barrel period): g = F/|d|^b first falls
    from 0; if it ever turns to rise while the ball overlaps the barrel (d > 0) and comes within
    twice its last change of zero, a new contact is possible and True is returned (also when the
    escape takes too long to sample). True only asks for a closer look, it is never an answer.
    """
    x1 = y0[0]
    v1 = y0[1]
    if p[10] != 0.0:
        return v1 > y0[3]
    m2 = p[5]
    k2 = p[6]
    inv_body = p[8]
    if inv_body == 0.0:
        centre = 0.0
        speed_c = 0.0
        share = 1.0
        r = y0[2]
        vr = y0[3]
        mu = m2
    else:
        mb = 1.0 / inv_body
        mass = m2 + mb
        centre = (m2 * y0[2] + mb * y0[4]) / mass
        speed_c = (m2 * y0[3] + mb * y0[5]) / mass
        share = mb / mass
        r = y0[2] - y0[4]
        vr = y0[3] - y0[5]
        mu = m2 * mb / mass
    if v1 >= speed_c:
        return True
    amplitude = math.sqrt(r * r + mu * vr * vr / k2)
    reach = share * amplitude
    lead = x1 - centre + reach
    if lead <= 0.0:
        return False
    if g_cannot_rise(x1 - y0[2], speed_c - v1, amplitude, share, mu, p):
        return False
    t_escape = lead / (speed_c - v1)
    if inv_body == 0.0:
        t_escape = min(t_escape, _force_escape_time(x1, v1, reach, p))
        if t_escape == 0.0:
            return False
    period = 2.0 * math.pi * math.sqrt(mu / k2)
    dt = min(t_escape, period) / SCREEN_POINTS
    n = math.ceil(t_escape / dt)
    if n > SCREEN_MAX_SAMPLES:
        return True
    y = y0.copy()
    k1 = np.zeros(6)
    k2v = np.zeros(6)
    k3 = np.zeros(6)
    k4 = np.zeros(6)
    tmp = np.zeros(6)
    g_old = 0.0
    falling = True
    for _ in range(n):
        _rhs_free(y, p, k1)
        for i in range(6):
            tmp[i] = y[i] + 0.5 * dt * k1[i]
        _rhs_free(tmp, p, k2v)
        for i in range(6):
            tmp[i] = y[i] + 0.5 * dt * k2v[i]
        _rhs_free(tmp, p, k3)
        for i in range(6):
            tmp[i] = y[i] + dt * k3[i]
        _rhs_free(tmp, p, k4)
        for i in range(6):
            y[i] += dt / 6.0 * (k1[i] + 2.0 * k2v[i] + 2.0 * k3[i] + k4[i])
        g = _gfun(y, p)
        d = y[0] - y[2]
        if g >= g_old:
            falling = False
        if not falling and d > 0.0 and g > -2.0 * abs(g - g_old):
            return True
        if d > 0.0 and g > 0.0:
            return True
        g_old = g
    return False


LANE_GROUPS = 64  # solve_many's units of parallel work: lanes first, first + 64, ... (even loads)


@nb.njit(cache=True)
def _solve_lanes(
    P: np.ndarray,
    v0: np.ndarray,
    length: np.ndarray,
    rtol: float,
    n_active: np.ndarray,
    t_max: np.ndarray,
    max_steps: int,
    cor: np.ndarray,
    tc: np.ndarray,
    nfev: np.ndarray,
    status: np.ndarray,
    states: np.ndarray,
    first: int,
    stride: int,
    series: int,
) -> None:
    """Lanes first, first + stride, ... one after another (compiled on its own, as solve_one is:
    inside the parallel loop's body the same calls ran about half again as long)."""
    for k in range(first, P.shape[0], stride):
        c, t, n, _, s = solve_one(
            P[k], v0[k], length[k], rtol, n_active[k], t_max[k], max_steps, states[k], series
        )
        cor[k] = c
        tc[k] = t
        nfev[k] = n
        status[k] = s


@nb.njit(cache=True, parallel=True)
def solve_many(
    P: np.ndarray,
    v0: np.ndarray,
    length: np.ndarray,
    rtol: float,
    n_active: np.ndarray,
    t_max: np.ndarray,
    max_steps: int,
    cor: np.ndarray,
    tc: np.ndarray,
    nfev: np.ndarray,
    status: np.ndarray,
    states: np.ndarray,
    series: int,
) -> None:
    """Solve n collisions in parallel lanes, each with its own steps and event (in LANE_GROUPS
    interleaved groups: neighbouring lanes, which cost alike, go to different threads); `series` as
    solve_one's."""
    groups = min(P.shape[0], LANE_GROUPS)
    for g in nb.prange(groups):
        _solve_lanes(
            P, v0, length, rtol, n_active, t_max, max_steps, cor, tc, nfev, status, states, g, groups, series
        )
