"""Variable projection for the pole-residue model: its basis, the linear solve and the exact Jacobian.

The model of modes.py and multipole.py, per FRF, with P poles p_r and real coefficients:
    H(k) = sum_r [a_r (g1 + g2) + b_r j (g1 - g2)] + C + D x_k,
    g1 = 1 / (1 - exp((p_r - s_k) dt)),  g2 = the same at conj(p_r),
so R_r = a_r + j b_r is the residue. Real and imaginary parts are stacked into a real basis A
(2K rows). The poles are the nonlinear parameters theta = (sigma_1, omega_1, sigma_2, ...) / w0,
p_r = (-theta_2r + j theta_2r+1) w0. For each theta the coefficients are the least-squares
solution c = A+ y, and the residual r = A c - y = -P y with P the projector off A's range.

Its Jacobian is Golub and Pereyra's (1973) exact derivative of the projected residual:
    dr/dtheta_k = P (dA/dtheta_k) c - (A+)^T (dA/dtheta_k)^T r,
where dA/dtheta_k has two non-zero columns, pole r's, since dg/dp = dt g (g - 1). A finite
difference Jacobian costs 2P more evaluations per step and most of the analysis's time.

The linear solve runs on unit-norm columns, by QR, or by the SVD (dropping what is below
RCOND of the largest singular value) where R is near singular (two poles on top of each other).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RCOND = 1e-12
N_LINE = 4  # per FRF: C and D, complex, as real columns 1, j, x, j x


def basis_columns(poles: np.ndarray, s: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """g1 and g2 of poles (b, P) at s (b, K): two (b, P, K)."""
    g1 = 1.0 / -np.expm1((poles[:, :, None] - s[:, None, :]) * dt)
    g2 = 1.0 / -np.expm1((np.conj(poles)[:, :, None] - s[:, None, :]) * dt)
    return g1, g2


def _stacked(cols: np.ndarray) -> np.ndarray:
    """Complex columns (b, n, K) as real matrices (b, 2K, n): real parts above imaginary parts."""
    return np.swapaxes(np.concatenate([cols.real, cols.imag], axis=-1), -1, -2)


def basis(g1: np.ndarray, g2: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The real bases (b, 2K, 2P + N_LINE) from g1, g2 (b, P, K) and x (b, K): per pole g1 + g2
    and j (g1 - g2), then 1, j, x, j x."""
    b, n, k = g1.shape
    cols = np.empty((b, 2 * n + N_LINE, k), dtype=complex)
    cols[:, 0 : 2 * n : 2] = g1 + g2
    cols[:, 1 : 2 * n : 2] = 1j * (g1 - g2)
    cols[:, 2 * n] = 1.0
    cols[:, 2 * n + 1] = 1j
    cols[:, 2 * n + 2] = x
    cols[:, 2 * n + 3] = 1j * x
    return _stacked(cols)


def basis_derivatives(
    g1: np.ndarray, g2: np.ndarray, dt: float, w0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """For g1, g2 (b, P, K) of poles scaled by w0 (b,): d(column 2r)/dtheta_k and
    d(column 2r+1)/dtheta_k, two (b, 2P, 2K) whose row k is the derivative of pole r = k // 2's
    two columns."""
    scale = dt * w0[:, None, None]
    d1 = scale * g1 * (g1 - 1.0)  # dg1/dp w0; dp/dsigma' = -w0, dp/domega' = j w0
    d2 = scale * g2 * (g2 - 1.0)  # dg2/dconj(p) w0; dconj(p)/domega' = -j w0
    b, n, k = g1.shape
    du = np.empty((b, 2 * n, k), dtype=complex)
    dv = np.empty_like(du)
    plus, minus = d1 + d2, d1 - d2
    du[:, 0::2] = -plus  # d(g1 + g2)/dtheta_2r
    dv[:, 0::2] = -1j * minus  # d(j (g1 - g2))/dtheta_2r
    du[:, 1::2] = 1j * minus  # d(g1 + g2)/dtheta_2r+1
    dv[:, 1::2] = -plus  # d(j (g1 - g2))/dtheta_2r+1
    return np.concatenate([du.real, du.imag], axis=-1), np.concatenate([dv.real, dv.imag], axis=-1)


@dataclass(frozen=True, eq=False)
class Projection:
    """Least-squares solves on a batch of bases A (b, rows, n): an orthonormal basis q of each
    range, and m with (A+)^T = q m diag(1/norms) (QR: m = R^-T; SVD: m = S^-1 V^T, the
    directions below RCOND zeroed in q and m alike)."""

    q: np.ndarray  # (b, rows, n)
    m: np.ndarray  # (b, n, n)
    norms: np.ndarray  # (b, n)

    @classmethod
    def of(cls, a: np.ndarray) -> Projection:
        """The solves on `a`'s unit-norm columns (a non-finite basis gives non-finite solves)."""
        norms = np.sqrt(np.einsum("bij,bij->bj", a, a))
        norms[norms == 0] = 1.0
        an = a / norms[:, None, :]
        q, r = np.linalg.qr(an)
        diag = np.abs(np.diagonal(r, axis1=-2, axis2=-1))
        fine = diag.min(axis=1) > RCOND * diag.max(axis=1)  # False where not finite
        if fine.all():
            return cls(q, np.linalg.inv(r).transpose(0, 2, 1), norms)
        m = np.full_like(r, np.nan)
        if fine.any():
            m[fine] = np.linalg.inv(r[fine]).transpose(0, 2, 1)
        for i in np.flatnonzero(~fine):
            if not np.all(np.isfinite(an[i])):
                q[i] = np.nan
                continue
            u, sv, vt = np.linalg.svd(an[i], full_matrices=False)
            keep = sv > RCOND * sv[0]
            inv = np.where(keep, 1.0 / np.where(keep, sv, 1.0), 0.0)
            q[i], m[i] = u * keep, vt * inv[:, None]
        return cls(q, m, norms)

    def subset(self, rows: np.ndarray) -> Projection:
        """The solves of some problems of the batch."""
        return Projection(self.q[rows], self.m[rows], self.norms[rows])

    def coefficients(self, y: np.ndarray) -> np.ndarray:
        """c = A+ y for y (b, rows, nrhs)."""
        return (self.m.transpose(0, 2, 1) @ (self.q.transpose(0, 2, 1) @ y)) / self.norms[:, :, None]

    def off_range(self, v: np.ndarray) -> np.ndarray:
        """(I - q q^T) v for v (b, k, rows, nrhs)."""
        q = self.q[:, None]
        return v - q @ (q.transpose(0, 1, 3, 2) @ v)

    def pinv_t(self, z: np.ndarray) -> np.ndarray:
        """(A+)^T z for z (b, k, n, nrhs)."""
        return self.q[:, None] @ (self.m[:, None] @ (z / self.norms[:, None, :, None]))


@dataclass(frozen=True, eq=False)
class Evaluation:
    """The model at poles theta (b, 2P) of the problems `rows` of a batch: g1 and g2 (b, P, K),
    residual r = A c - y (b, 2K, nrhs), coefficients c (b, n, nrhs) and the bases' solves."""

    rows: np.ndarray
    theta: np.ndarray
    g1: np.ndarray
    g2: np.ndarray
    r: np.ndarray
    c: np.ndarray
    solve: Projection

    def subset(self, pick: np.ndarray) -> Evaluation:
        """The evaluation of some of these problems."""
        return Evaluation(
            self.rows[pick],
            self.theta[pick],
            self.g1[pick],
            self.g2[pick],
            self.r[pick],
            self.c[pick],
            self.solve.subset(pick),
        )

    @property
    def residuals(self) -> np.ndarray:
        """The residual vectors (b, nrhs 2K): each FRF's 2K residuals in turn."""
        return self.r.transpose(0, 2, 1).reshape(self.r.shape[0], -1)


class PoleModel:
    """The projected residuals of a batch of B problems and their exact Jacobians (module docstring).

    Problem i fits y[i] (2K, nrhs) at s[i] and x[i] (K,) with poles scaled by w0[i]; bins where
    used[i] is False (padding, so that bands of different widths share one batch) are zero rows of
    both y and the basis, so they change nothing."""

    def __init__(
        self, y: np.ndarray, s: np.ndarray, dt: float, x: np.ndarray, w0: np.ndarray, used: np.ndarray
    ) -> None:
        self.y, self.s, self.dt, self.x, self.w0 = y, s, dt, x, w0
        self.used = used[:, None, :]  # (B, 1, K)
        self.padded = not np.all(used)

    def poles(self, theta: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """p_r = (-theta_2r + j theta_2r+1) w0 of the problems `rows`, for theta (b, 2P)."""
        return (-theta[:, 0::2] + 1j * theta[:, 1::2]) * self.w0[rows, None]

    def evaluate(self, theta: np.ndarray, rows: np.ndarray) -> Evaluation:
        """The model at theta (b, 2P) for the problems `rows` (b,) of the batch."""
        g1, g2 = basis_columns(self.poles(theta, rows), self.s[rows], self.dt)
        if self.padded:
            g1, g2 = g1 * self.used[rows], g2 * self.used[rows]
        a = basis(g1, g2, self.x[rows])  # x is 0 where unused
        if self.padded:
            a[:, :, -N_LINE:-2] *= np.concatenate([self.used[rows], self.used[rows]], axis=2).transpose(
                0, 2, 1
            )
        solve = Projection.of(a)
        y = self.y[rows]
        c = solve.coefficients(y)
        return Evaluation(rows, theta, g1, g2, a @ c - y, c, solve)

    def residuals(self, theta: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, Evaluation]:
        """The residual vectors (b, m) at theta and the evaluation (levmar's fun)."""
        ev = self.evaluate(theta, rows)
        return ev.residuals, ev

    def jacobian(self, ev: Evaluation) -> np.ndarray:
        """d residuals / d theta (b, m, 2P), Golub-Pereyra (module docstring)."""
        r, c, solve = ev.r, ev.c, ev.solve
        du, dv = basis_derivatives(ev.g1, ev.g2, self.dt, self.w0[ev.rows])  # zero where unused
        b, n_par = ev.theta.shape
        k = np.arange(n_par)
        col = 2 * (k // 2)  # column 2r of parameter k's pole r
        # P (dA_k c): dA_k c = du_k c[2r] + dv_k c[2r+1], (b, 2P, 2K, nrhs)
        t1 = du[..., None] * c[:, col, None, :] + dv[..., None] * c[:, col + 1, None, :]
        # (A+)^T (dA_k^T r): dA_k^T r is non-zero in rows 2r, 2r+1 only
        z = np.zeros((b, n_par, c.shape[1], c.shape[2]))
        z[:, k, col] = du @ r
        z[:, k, col + 1] = dv @ r
        jac = solve.off_range(t1) - solve.pinv_t(z)
        return jac.transpose(0, 3, 2, 1).reshape(b, -1, n_par)
