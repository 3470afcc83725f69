"""Poles fitted jointly to the two FRFs over a band, many fits solved together.

The model of modes.py with P poles sharing the two FRFs over one band:
    H_i(k) = sum_r [R_ir / (1 - exp((p_r - s_k) dt)) + conj(R_ir) / (1 - exp((conj(p_r) - s_k) dt))]
             + C_i + D_i x_k
Residues and lines are linear, solved for every trial set of poles (variable projection,
varpro.py, with its exact Jacobian); the poles by a bounded Levenberg-Marquardt (levmar.py) that
takes every fit with the same number of poles in one batch, bands of different widths padded.
The Jacobian gives each frequency's standard uncertainty, scaled by sqrt(ENBW in bins) as in
modes.py.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.modal import levmar
from rig.modal.varpro import N_LINE, Evaluation, PoleModel

X_SCALE = 1e-3  # the poles' scale in units of w0: 0.1 % of the frequency


@dataclass(frozen=True)
class MultiFit:
    """Poles fitted together over one band of bins."""

    poles: tuple[complex, ...]  # ascending frequency
    residues: tuple[tuple[complex, complex], ...]  # per pole: at accelerometer 1 and 2
    u_frequency_hz: tuple[float, ...]  # per pole, standard uncertainty from the Jacobian
    cost: float  # half the sum of squared (scaled) residuals
    n_residuals: int
    bins: tuple[int, int]
    residual: np.ndarray  # (2, K) complex, in the FRFs' units

    @property
    def frequencies_hz(self) -> tuple[float, ...]:
        """Natural frequencies |p| / 2 pi."""
        return tuple(abs(p) / (2 * math.pi) for p in self.poles)

    @property
    def damping_ratios(self) -> tuple[float, ...]:
        """sigma / |p| per pole."""
        return tuple(-p.real / abs(p) for p in self.poles)

    @property
    def n_params(self) -> int:
        """Fitted real parameters: 2 per pole, and per FRF 2 per residue and the line."""
        return n_params(len(self.poles))


def n_params(poles: int) -> int:
    """Real parameters of a fit of `poles` poles: 2 per pole, per FRF 2 per residue and the line."""
    return 2 * poles + 2 * (2 * poles + N_LINE)


@dataclass(frozen=True)
class Problem:
    """One fit: the FRFs h (2, K) at s (K,) over `bins`, from these guessed poles."""

    h: np.ndarray
    s: np.ndarray
    guesses: tuple[complex, ...]
    bins: tuple[int, int]


def fit_poles(
    h: np.ndarray, s: np.ndarray, dt: float, guesses: Sequence[complex], enbw: float, bins: tuple[int, int]
) -> MultiFit | None:
    """Fit len(guesses) poles jointly to the FRFs h (2, K) at s (K,); None if the fit fails."""
    return fit_many([Problem(h, s, tuple(guesses), bins)], dt, enbw)[0]


def fit_many(problems: Sequence[Problem], dt: float, enbw: float) -> list[MultiFit | None]:
    """`fit_poles` of every problem; those with the same number of poles are solved together."""
    out: list[MultiFit | None] = [None] * len(problems)
    for n in sorted({len(p.guesses) for p in problems}):
        which = [i for i, p in enumerate(problems) if len(p.guesses) == n]
        for i, fit in zip(which, _fit_batch([problems[i] for i in which], dt, enbw), strict=True):
            out[i] = fit
    return out


def _fit_batch(problems: list[Problem], dt: float, enbw: float) -> list[MultiFit | None]:
    """Problems with the same number of poles, padded to the widest band and solved at once."""
    n = len(problems[0].guesses)
    sizes = np.array([p.s.size for p in problems])
    fits: list[MultiFit | None] = [None] * len(problems)
    fit_rows = np.flatnonzero(4 * sizes > n_params(n))  # residuals: 2 FRFs x 2K real
    if fit_rows.size == 0:
        return fits
    width = int(sizes.max())
    b = len(problems)
    s = np.empty((b, width), dtype=complex)
    hs = np.zeros((b, 2, width), dtype=complex)
    used = np.zeros((b, width), dtype=bool)
    for i, p in enumerate(problems):
        k = p.s.size
        s[i, :k], s[i, k:] = p.s, p.s[-1]
        hs[i, :, :k], used[i, :k] = p.h, True
    w0 = np.array([np.mean([abs(g) for g in p.guesses]) for p in problems])
    omega = s.imag
    lo = np.array([p.s.imag.min() for p in problems]) / w0
    hi = np.array([p.s.imag.max() for p in problems]) / w0
    centre = np.array([p.s.imag.mean() for p in problems])
    x = np.where(used, (omega - centre[:, None]) / w0[:, None], 0.0)
    scale = np.max(np.abs(hs), axis=2)  # (b, 2)
    scale[scale == 0] = 1.0
    y = np.concatenate([hs.real, hs.imag], axis=2).transpose(0, 2, 1) / scale[:, None, :]  # (b, 2K, 2)
    model = PoleModel(y, s, dt, x, w0, used)
    guess = np.array([p.guesses for p in problems]) / w0[:, None]  # (b, n)
    theta0 = np.empty((b, 2 * n))
    theta0[:, 0::2] = np.clip(-guess.real, 1e-6, 0.49)
    theta0[:, 1::2] = np.clip(guess.imag, lo[:, None] + 1e-9, hi[:, None] - 1e-9)
    lower = np.empty((b, 2 * n))
    upper = np.empty((b, 2 * n))
    lower[:, 0::2], upper[:, 0::2] = 0.0, 0.5
    lower[:, 1::2], upper[:, 1::2] = lo[:, None], hi[:, None]
    sol = levmar.solve(
        model.residuals,
        model.jacobian,
        Evaluation.subset,
        theta0[fit_rows],
        lower[fit_rows],
        upper[fit_rows],
        rows=fit_rows,
        x_scale=X_SCALE,
    )
    poles = model.poles(sol.x, fit_rows)
    inside = (lo[fit_rows, None] * w0[fit_rows, None] < poles.imag) & (
        poles.imag < hi[fit_rows, None] * w0[fit_rows, None]
    )
    ok = sol.success & np.all(np.isfinite(sol.x), axis=1) & np.all(inside, axis=1)
    if not ok.any():
        return fits
    ev = model.evaluate(sol.x[ok], fit_rows[ok])
    jac = model.jacobian(ev)
    for j, (i, p) in enumerate(zip(fit_rows[ok], poles[ok], strict=True)):
        k = problems[i].s.size
        r = ev.r[j] * scale[i]
        r = np.concatenate([r[:k], r[width : width + k]])  # the band's own rows
        rows = np.concatenate([np.arange(k), width + np.arange(k)])
        jac_i = jac[j].reshape(2, 2 * width, 2 * n)[:, rows].reshape(-1, 2 * n)
        fits[i] = _multifit(
            p, ev.c[j] * scale[i], r, jac_i, float(sol.cost[ok][j]), w0[i], enbw, problems[i].bins
        )
    return fits


def _multifit(
    poles: np.ndarray,
    coefs: np.ndarray,
    r: np.ndarray,
    jac: np.ndarray,
    cost: float,
    w0: float,
    enbw: float,
    bins: tuple[int, int],
) -> MultiFit:
    """The fit's poles in ascending frequency with their residues, uncertainties and residual."""
    n = poles.size
    k = r.shape[0] // 2
    m = r.size
    s2 = 2.0 * cost / (m - n_params(n))
    try:
        cov = s2 * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cov = np.full((2 * n, 2 * n), np.nan)
    u = []
    for i, p in enumerate(poles):
        grad = np.array([-p.real, p.imag]) / abs(p) * w0
        block = cov[2 * i : 2 * i + 2, 2 * i : 2 * i + 2]
        var = float(grad @ block @ grad)
        u.append(
            math.sqrt(var * max(enbw, 1.0)) / (2 * math.pi) if math.isfinite(var) and var >= 0 else math.inf
        )
    order = np.argsort(np.abs(poles))
    res = [
        (complex(coefs[2 * i, 0], coefs[2 * i + 1, 0]), complex(coefs[2 * i, 1], coefs[2 * i + 1, 1]))
        for i in order
    ]
    return MultiFit(
        tuple(complex(poles[i]) for i in order),
        tuple(res),
        tuple(u[i] for i in order),
        cost,
        m,
        bins,
        (r[:k] + 1j * r[k:]).T,
    )


def peak_height(fit: MultiFit, i: int, dt: float, tau: float) -> float:
    """|H| that pole i alone gives at its own frequency on the more responsive accelerometer."""
    p = fit.poles[i]
    s = 1j * p.imag + 1.0 / tau
    g = 1.0 / -np.expm1((p - s) * dt)
    return max(abs(r) * abs(g) for r in fit.residues[i])
