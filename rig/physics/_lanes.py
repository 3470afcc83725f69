"""The kernel's DOP853 over many collisions at once, as numpy arrays: no numba, for a few hundred solves.

Loading numba and the compiled kernel costs about a second, more than a `rig model crosscheck`
of 40 bats spends solving (7 x 40 solves). Here every lane (one collision) takes the kernel's own
steps side by side: the same tables (`_dop853`'s, read from scipy), the same stage sums over their
nonzero terms in the same order, the same error norm, step control, end-of-contact location on
the 7th-order dense output and re-contact screen, each lane with its own step size, rejections
and end. What differs is only how the arithmetic is issued: one numpy operation over all the
lanes still in contact instead of one scalar loop per lane, so the results agree with the compiled
kernel's to the last bit (tests/physics/test_lanes.py; x ** y is taken from the C library as the
compiled kernel takes it, see `_pow`). The re-contact screen after each separation runs lane by
lane: the interpreted kernel's own `may_meet_again`.

Arrays are laid out state-major: y[i] is state i over the lanes, p[j] parameter j over the lanes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rig.physics import _interpreted

_k = _interpreted.load()  # the kernel's source run by the interpreter: its tables and per-lane steps

# x ** y as the compiled kernel computes it (the C library's pow): np.power runs a SIMD pow on
# AVX-512 machines, off by one unit in the last place in ~5 % of cases, and near-rigid barrels'
# thousands of steps then part ways with the compiled kernel's (within rtol, but no longer to rounding)
_pow = np.float_power

_Arr = np.ndarray
_Rows = tuple[np.ndarray, np.ndarray, np.ndarray]  # a table's nonzero terms: row starts, columns, values
_A: _Rows = (_k._A_START, _k._A_COL, _k._A_VAL)
_D: _Rows = (_k._D_START, _k._D_COL, _k._D_VAL)
_B = (_k._B_COL, _k._B_VAL)
_E = (_k._E_COL, _k._E5_VAL, _k._E3_VAL)


def _rhs(y: np.ndarray, p: np.ndarray, rigid: np.ndarray | None, out: np.ndarray) -> None:
    """`_kernel_model.rhs` over lanes (rigid: the lanes with a rigid barrel, None if there are none)."""
    d = y[0] - y[2]
    dd = y[1] - y[3]
    ad = np.abs(d)
    f = p[1] * d * _pow(ad, p[3]) + p[2] * dd * _pow(ad, p[4])
    out[0] = y[1]
    out[1] = -f / p[0]
    out[2] = y[3]
    fs = p[6] * (y[2] - y[4]) + p[7] * (y[3] - y[5])
    out[3] = (f - fs) / p[5]
    out[4] = y[5]
    out[5] = fs * p[8]
    if rigid is not None:
        acc = f * p[9]
        out[3] = np.where(rigid, acc, out[3])
        out[5] = np.where(rigid, acc, out[5])


def _gfun(y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """`_kernel_model.gfun` over lanes."""
    d = y[0] - y[2]
    ad = np.abs(d)
    spring = np.where(ad > 0.0, p[1] * d * _pow(ad, (p[3] - p[4])), 0.0)
    return spring + p[2] * (y[1] - y[3])


def _gdot(y: np.ndarray, f: np.ndarray, p: np.ndarray) -> np.ndarray:
    """`_kernel_model.gdot` over lanes."""
    d = y[0] - y[2]
    ad = np.abs(d)
    dd = y[1] - y[3]
    spring = np.where(ad > 0.0, p[1] * (1.0 + p[3] - p[4]) * _pow(ad, (p[3] - p[4])) * dd, 0.0)
    return spring + p[2] * (f[1] - f[3])


def _damping_rate(y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """`_kernel_model.damping_rate` over lanes."""
    inv = 1.0 / p[0] + np.where(p[10] != 0.0, p[9], 1.0 / p[5])
    ad = np.abs(y[0] - y[2])
    lam = p[2] * _pow(ad, p[4]) * inv
    return np.where(lam * lam <= 4.0 * p[1] * (1.0 + p[3]) * _pow(ad, p[3]) * inv, 0.0, lam)


def _combine(K: np.ndarray, cols: np.ndarray, vals: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """sum over q in lo..hi-1 of vals[q] * K[cols[q]], the terms added in the kernel's order."""
    acc = vals[lo] * K[cols[lo]]
    for q in range(lo + 1, hi):
        acc += vals[q] * K[cols[q]]
    return acc


@dataclass
class _Model:
    """What the right-hand side needs of the lanes beside their parameters."""

    p: np.ndarray  # parameters, 11 x lanes
    rigid: np.ndarray | None  # lanes with a rigid barrel (None: none)
    still: np.ndarray | None  # 6 x lanes: the states that do not move (the kernel's _moving; None: all move)

    def rhs(self, y: np.ndarray, out: np.ndarray) -> None:
        _rhs(y, self.p, self.rigid, out)
        if self.still is not None:
            np.putmask(out, self.still, 0.0)  # as the kernel, which leaves those states out of its sums

    def take(self, rows: np.ndarray) -> _Model:
        rigid = None if self.rigid is None else self.rigid[rows]
        still = None if self.still is None else self.still[:, rows]
        return _Model(self.p[:, rows], rigid, still)


def _model(P: np.ndarray) -> _Model:
    """The lanes' model from the kernel's parameter rows (lanes x 11)."""
    p = np.ascontiguousarray(P.T)
    rigid = p[10] != 0.0
    moving = np.where(p[8] != 0.0, 6, np.where(rigid, 2, 4))
    still = np.arange(6)[:, None] >= moving[None, :]
    return _Model(p, rigid if rigid.any() else None, still if still.any() else None)


def _stages(y: np.ndarray, h: np.ndarray, model: _Model, K: np.ndarray, first: int, last: int) -> None:
    """Stages first..last-1 into K (stages x 6 x lanes), as the kernel's `_stages`."""
    starts, cols, vals = _A
    for s in range(first, last):
        model.rhs(y + h * _combine(K, cols, vals, int(starts[s]), int(starts[s + 1])), K[s])


def _dense(
    y: np.ndarray,
    ynew: np.ndarray,
    f: np.ndarray,
    fnew: np.ndarray,
    h: np.ndarray,
    model: _Model,
    K: np.ndarray,
) -> np.ndarray:
    """The 7th-order dense output's coefficients (7 x 6 x lanes) of the step just taken."""
    _stages(y, h, model, K, _k._NS + 1, _k._NX)
    F = np.empty((7, *y.shape))
    dy = ynew - y
    F[0] = dy
    F[1] = h * f - dy
    F[2] = 2.0 * dy - h * (fnew + f)
    starts, cols, vals = _D
    for r in range(4):
        F[3 + r] = h * _combine(K, cols, vals, int(starts[r]), int(starts[r + 1]))
    return F


def _interpolate(y: np.ndarray, F: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The dense output at x (0..1 of each lane's step), as the kernel's `_interpolate`."""
    acc = F[6] * x
    for k in range(5, -1, -1):
        acc += F[k]
        acc *= x if (6 - k) % 2 == 0 else 1.0 - x
    return y + acc


@dataclass
class _Ends:
    """Lanes whose contact ends inside their last step: what locating the end needs, gathered."""

    parts: list[tuple[np.ndarray, ...]] = field(default_factory=list)

    def add(self, *arrays: np.ndarray) -> None:
        self.parts.append(arrays)

    def joined(self) -> list[np.ndarray]:
        return [np.concatenate(a, axis=-1) for a in zip(*self.parts, strict=True)]


def _locate(
    y: np.ndarray, F: np.ndarray, p: np.ndarray, glo: np.ndarray, ghi: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """x in (0, hi] where g falls through zero (Illinois on the dense output, as the kernel: each lane
    iterates until its bracket is closed, then stops)."""
    lo = np.zeros_like(hi)
    hi = hi.copy()
    glo = glo.copy()
    ghi = ghi.copy()
    side = np.zeros(hi.shape, dtype=np.int64)
    live = np.arange(hi.size)
    for _ in range(100):
        if not live.size:
            break
        L = live
        x = (lo[L] * ghi[L] - hi[L] * glo[L]) / (ghi[L] - glo[L])
        outside = ~((lo[L] < x) & (x < hi[L]))
        x[outside] = 0.5 * (lo[L][outside] + hi[L][outside])
        gx = _gfun(_interpolate(y[:, L], F[:, :, L], x), p[:, L])
        up = gx > 0.0
        u, d = L[up], L[~up]
        ghi[u[side[u] == 1]] *= 0.5
        lo[u], glo[u], side[u] = x[up], gx[up], 1
        glo[d[side[d] == -1]] *= 0.5
        hi[d], ghi[d], side[d] = x[~up], gx[~up], -1
        closed = (hi[L] - lo[L] <= 4e-16 * np.maximum(1.0, hi[L])) | (gx == 0.0)
        live = L[~closed]
    return hi


@dataclass
class _Lanes:
    """The lanes still stepping: state-major arrays over them, and where each one's results go."""

    ids: np.ndarray
    model: _Model
    v0: np.ndarray
    length: np.ndarray
    n_active: np.ndarray
    t_max: np.ndarray
    atol: np.ndarray
    y: np.ndarray
    f: np.ndarray
    t: np.ndarray
    h: np.ndarray
    g_old: np.ndarray
    gd_old: np.ndarray
    rejected: np.ndarray
    steps: np.ndarray
    nfev: np.ndarray

    def keep(self, rows: np.ndarray) -> None:
        """Keep only these lanes (boolean mask or indices)."""
        for name, value in list(vars(self).items()):
            if name == "model":
                self.model = value.take(rows)
            else:
                setattr(self, name, value[..., rows])


def _start(
    P: np.ndarray, v0: np.ndarray, length: np.ndarray, rtol: float, n_active: np.ndarray, t_max: np.ndarray
) -> _Lanes:
    """Every lane at the first touch, as the kernel's solve_one begins."""
    n = P.shape[0]
    model = _model(P)
    y = np.zeros((6, n))
    y[1] = v0
    f = np.empty((6, n))
    model.rhs(y, f)
    atol = np.where((np.arange(6) % 2 == 0)[:, None], rtol * length, rtol * v0)
    return _Lanes(
        ids=np.arange(n),
        model=model,
        v0=v0.astype(float),
        length=length.astype(float),
        n_active=n_active.astype(float),
        t_max=t_max.astype(float),
        atol=atol,
        y=y,
        f=f,
        t=np.zeros(n),
        h=1e-4 * length / v0,
        g_old=_gfun(y, model.p),
        gd_old=np.full(n, math.nan),
        rejected=np.zeros(n, dtype=bool),
        steps=np.zeros(n, dtype=np.int64),
        nfev=np.ones(n, dtype=np.int64),
    )


_SAFETY, _MIN_FACTOR, _MAX_FACTOR, _EXPONENT = _k._SAFETY, _k._MIN_FACTOR, _k._MAX_FACTOR, _k._EXPONENT


@dataclass
class _Out:
    """The caller's result arrays (solve_many's), filled lane by lane as each ends."""

    cor: np.ndarray
    tc: np.ndarray
    nfev: np.ndarray
    status: np.ndarray
    states: np.ndarray

    def stop(self, lanes: _Lanes, rows: np.ndarray, status: np.ndarray) -> None:
        """Lanes that end without a result (a status other than OK or FOLLOW)."""
        ids = lanes.ids[rows]
        self.cor[ids] = math.nan
        self.tc[ids] = lanes.t[rows]
        self.nfev[ids] = lanes.nfev[rows]
        self.status[ids] = status


def _limits(lanes: _Lanes, max_steps: int) -> np.ndarray:
    """Each lane's status from the checks at the top of the kernel's loop (-1: none applies)."""
    underflow = lanes.h < 1e-14 * np.maximum(lanes.t, lanes.length / lanes.v0)
    status = np.where(underflow, _k.STATUS_STEP_UNDERFLOW, -1)
    status = np.where(lanes.t >= lanes.t_max, _k.STATUS_TIME_LIMIT, status)
    return np.where(lanes.steps >= max_steps, _k.STATUS_MAX_STEPS, status)


def _error(lanes: _Lanes, K: np.ndarray, ynew: np.ndarray, rtol: float) -> np.ndarray:
    """The step's error norm (scipy's DOP853 form, the kernel's arithmetic)."""
    cols, e5v, e3v = _E
    a5 = _combine(K, cols, e5v, 0, cols.size)
    a3 = _combine(K, cols, e3v, 0, cols.size)
    sc = lanes.atol + rtol * np.maximum(np.abs(lanes.y), np.abs(ynew))
    q5 = a5 / sc
    q3 = a3 / sc
    q5 = q5 * q5  # as the kernel: a square as q * q
    q3 = q3 * q3
    e5 = q5[0].copy()
    e3 = q3[0].copy()
    for i in range(1, 6):
        e5 += q5[i]
        e3 += q3[i]
    err = np.abs(lanes.h) * e5 / np.sqrt((e5 + 0.01 * e3) * lanes.n_active)
    return np.where((e5 == 0.0) & (e3 == 0.0), 0.0, err)


_INVPHI = 0.6180339887498949


def _minima(y: np.ndarray, F: np.ndarray, p: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Where g is least on each lane's dense output, and g there: the kernel's golden-section
    `_minimum`, each lane stopping where the kernel's would (at a point where g <= 0, or when its
    bracket is below `width`, the kernel's `dip_width`)."""
    m = y.shape[1]
    lo, hi = np.zeros(m), np.ones(m)
    c = hi - _INVPHI * (hi - lo)
    d = lo + _INVPHI * (hi - lo)
    gc = _gfun(_interpolate(y, F, c), p)
    gd = _gfun(_interpolate(y, F, d), p)
    x_min, g_min = np.empty(m), np.empty(m)
    live = np.arange(m)
    settled: list[np.ndarray] = []
    for _ in range(60):
        at_c = gc[live] <= 0.0
        at_d = ~at_c & (gd[live] <= 0.0) & (gc[live] > gd[live])
        for done, x, g in ((at_c, c, gc), (at_d, d, gd)):
            x_min[live[done]], g_min[live[done]] = x[live[done]], g[live[done]]
        L = live[~(at_c | at_d)]
        left = gc[L] < gd[L]
        a, b = L[left], L[~left]
        hi[a], d[a], gd[a] = d[a], c[a], gc[a]
        c[a] = hi[a] - _INVPHI * (hi[a] - lo[a])
        lo[b], c[b], gc[b] = c[b], d[b], gd[b]
        d[b] = lo[b] + _INVPHI * (hi[b] - lo[b])
        x = np.where(left, c[L], d[L])
        g = _gfun(_interpolate(y[:, L], F[:, :, L], x), p[:, L])
        gc[a], gd[b] = g[left], g[~left]
        closed = hi[L] - lo[L] < width
        settled.append(L[closed])
        live = L[~closed]
        if not live.size:
            break
    rest = np.concatenate([*settled, live])  # closed brackets, and any still open after 60 steps
    at_c = gc[rest] < gd[rest]
    x_min[rest] = np.where(at_c, c[rest], d[rest])
    g_min[rest] = np.where(at_c, gc[rest], gd[rest])
    return x_min, g_min


def _finish(ends: _Ends, out: _Out) -> None:
    """Locate each ended lane's separation on its dense output; screen it for a later contact."""
    if not ends.parts:
        return
    ids, y, F, p, h, t, v0, glo, ghi, hi_start, nfev = ends.joined()
    x = _locate(y, F, p, glo, ghi, hi_start)
    state = _interpolate(y, F, x)
    finite = np.all(np.isfinite(state), axis=0)
    out.states[ids] = state.T
    out.nfev[ids] = nfev
    out.cor[ids] = np.where(finite, -state[1] / v0, math.nan)
    out.tc[ids] = np.where(finite, t + x * h, t)
    out.status[ids] = _k.STATUS_NOT_FINITE
    for j in np.flatnonzero(finite):
        again = _k.may_meet_again(out.states[ids[j]], np.ascontiguousarray(p[:, j]))
        out.status[ids[j]] = _k.STATUS_FOLLOW if again else _k.STATUS_OK


def _step(lanes: _Lanes, rtol: float, kappa: float, ends: _Ends) -> np.ndarray:
    """One step attempted in every lane, as one pass of the kernel's loop; the lanes that ended."""
    m = lanes.ids.size
    y, f, h, model = lanes.y, lanes.f, lanes.h, lanes.model
    K = np.empty((_k._NX, 6, m))
    K[0] = f
    _stages(y, h, model, K, 1, _k._NS)
    cols, vals = _B
    ynew = y + h * _combine(K, cols, vals, 0, cols.size)
    fnew = K[_k._NS]
    model.rhs(ynew, fnew)
    lanes.nfev += _k._NS
    lanes.steps += 1
    err = _error(lanes, K, ynew, rtol)
    accepted = err < 1.0  # False where err is not finite
    shrink = np.where(np.isfinite(err), np.maximum(_MIN_FACTOR, _SAFETY * _pow(err, _EXPONENT)), _MIN_FACTOR)
    lanes.h = np.where(accepted, h, h * shrink)
    lanes.rejected |= ~accepted
    g_new = _gfun(ynew, model.p)
    crossed = accepted & (lanes.g_old > 0.0) & (g_new <= 0.0)
    look = accepted & ~crossed & (lanes.g_old > 0.0)
    lanes.gd_old = np.where(look & np.isnan(lanes.gd_old), _gdot(y, f, model.p), lanes.gd_old)
    falling = look & (lanes.gd_old < 0.0)
    gd_new = np.where(falling, _gdot(ynew, fnew, model.p), math.nan)
    dip = falling & (gd_new > 0.0)
    ending = crossed | dip
    if ending.any():
        lam = _damping_rate(y, model.p)
        retake = ending & (h * lam > kappa)  # the step holding the end must resolve the decay
        lanes.h = np.where(retake, 0.9 * kappa / lam, lanes.h)
        lanes.rejected |= retake
        accepted &= ~retake
        crossed &= ~retake
        dip &= ~retake
        rows = np.flatnonzero(crossed | dip)
        if rows.size:
            F = _dense(
                y[:, rows], ynew[:, rows], f[:, rows], fnew[:, rows], h[rows], model.take(rows), K[:, :, rows]
            )
            lanes.nfev[rows] += _k._NX - _k._NS - 1
            hi_start = np.ones(rows.size)
            in_dip = np.flatnonzero(dip[rows])
            if in_dip.size:  # g has a minimum inside the step: contact ends there if it reaches 0
                r = rows[in_dip]
                x_min, g_min = _minima(y[:, r], F[:, :, in_dip], model.p[:, r], _k.dip_width(rtol))
                low = g_min <= 0.0
                crossed[rows[in_dip[low]]] = True
                g_new[rows[in_dip[low]]] = g_min[low]
                hi_start[in_dip[low]] = x_min[low]
            sel = crossed[rows]
            r = rows[sel]
            ends.add(
                lanes.ids[r],
                y[:, r],
                F[:, :, sel],
                model.p[:, r],
                h[r],
                lanes.t[r],
                lanes.v0[r],
                lanes.g_old[r],
                g_new[r],
                hi_start[sel],
                lanes.nfev[r],
            )
    move = accepted & ~crossed
    factor = np.where(err == 0.0, _MAX_FACTOR, np.minimum(_MAX_FACTOR, _SAFETY * _pow(err, _EXPONENT)))
    factor = np.where(lanes.rejected, np.minimum(1.0, factor), factor)
    lanes.t = np.where(move, lanes.t + h, lanes.t)
    lanes.h = np.where(move, h * factor, lanes.h)
    lanes.rejected &= ~move
    lanes.g_old = np.where(move, g_new, lanes.g_old)
    lanes.gd_old = np.where(move, gd_new, lanes.gd_old)
    lanes.y = np.where(move, ynew, y)
    lanes.f = np.where(move, fnew, f)
    return crossed


def solve_many(
    P: _Arr,
    v0: _Arr,
    length: _Arr,
    rtol: float,
    n_active: _Arr,
    t_max: _Arr,
    max_steps: int,
    cor: _Arr,
    tc: _Arr,
    nfev: _Arr,
    status: _Arr,
    states: _Arr,
    series: int,
) -> None:
    """`_dop853.solve_many`'s call, every lane stepped side by side in numpy, DOP853 throughout
    (`series` must be 0); cor, tc, nfev, status and states are filled in."""
    if series:
        raise ValueError("the numpy lanes take DOP853 steps throughout (series 0)")
    out = _Out(cor, tc, nfev, status, states)
    kappa = min(1.0, (40320.0 * rtol) ** 0.125)
    ends = _Ends()
    with np.errstate(all="ignore"):
        lanes = _start(P, v0, length, rtol, n_active, t_max)
        while lanes.ids.size:
            limit = _limits(lanes, max_steps)
            stopped = limit >= 0
            if stopped.any():
                out.stop(lanes, stopped, limit[stopped])
                lanes.keep(~stopped)
                if not lanes.ids.size:
                    break
            ended = _step(lanes, rtol, kappa, ends)
            if ended.any():
                lanes.keep(~ended)
        _finish(ends, out)
