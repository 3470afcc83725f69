"""A bounded Levenberg-Marquardt solver for a batch of small least-squares problems at once.

The pole fits have 2 to 8 parameters and a few hundred residuals: scipy.optimize.least_squares
spent more time in its own bookkeeping (about 0.1 ms a step) than in the model, and solves one
problem at a time. Here B problems of the same shape take their steps together (stacked numpy),
each with its own damping lambda, and a problem leaves the batch when it has converged.

Per step, in variables scaled by x_scale: solve (J^T J + lambda I) d = -J^T r, with the
variables held at a bound by a gradient pushing outward left out; take x + d clipped into the
bounds; accept it if the cost fell, then lower lambda by Nielsen's rule, else raise it. Stop as
least_squares does: the cost falls by less than ftol of itself on a step the model predicted
well, the step is below xtol of |x|, or the gradient J^T r below gtol; or give up (success
False) after max_nfev evaluations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

# fun(x (b, n), rows (b,)) -> residuals (b, m) and a state; jac(state) -> (b, m, n); rows index the batch
Fun = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, Any]]
Jac = Callable[[Any], np.ndarray]
Subset = Callable[[Any, np.ndarray], Any]  # the state of some problems of a batch's state


@dataclass(frozen=True)
class Solution:
    """Per problem: the solution, half the sum of squared residuals, and whether it converged."""

    x: np.ndarray  # (B, n)
    cost: np.ndarray  # (B,)
    success: np.ndarray  # (B,) bool
    nfev: np.ndarray  # (B,) evaluations of the residuals


def solve(
    fun: Fun,
    jac: Jac,
    subset: Subset,
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    rows: np.ndarray | None = None,
    x_scale: float = 1.0,
    ftol: float = 1e-8,
    xtol: float = 1e-8,
    gtol: float = 1e-8,
    max_nfev: int | None = None,
) -> Solution:
    """Minimise 0.5 |fun(x, rows)|^2 for each row of x0 (B, n) inside [lower, upper] (B, n);
    `rows` (default 0..B-1) are the problems' indices that fun is given."""
    x = np.clip(np.array(x0, dtype=float), lower, upper)
    b, n = x.shape
    limit = max_nfev if max_nfev is not None else 100 * n
    rows = np.arange(b) if rows is None else rows
    r, state = fun(x, rows)
    cost = 0.5 * np.einsum("bm,bm->b", r, r)
    nfev = np.ones(b, dtype=int)
    done = np.zeros(b, dtype=bool)
    success = np.zeros(b, dtype=bool)
    js = jac(state) * x_scale
    a = np.einsum("bmi,bmj->bij", js, js)
    g = np.einsum("bmi,bm->bi", js, r)
    lam = 1e-3 * np.max(np.diagonal(a, axis1=1, axis2=2), axis=1)
    lam[~(lam > 0)] = 1.0  # a zero Jacobian (lam 0) or a non-finite one
    nu = np.full(b, 2.0)
    done[~np.isfinite(cost) | ~np.all(np.isfinite(g), axis=1)] = True  # no start: not a success
    eye = np.eye(n)
    while True:
        live = np.flatnonzero(~done)
        if live.size == 0:
            break
        xs, lo, hi = x[live], lower[live], upper[live]
        gl, al = g[live], a[live]
        # variables at a bound with the gradient pushing outward stay there
        held = ((xs <= lo) & (gl > 0)) | ((xs >= hi) & (gl < 0))
        flat = np.max(np.abs(np.where(held, 0.0, gl)), axis=1) < gtol * x_scale  # |J^T r| < gtol
        if flat.any():
            success[live[flat]] = done[live[flat]] = True
            keep = ~flat
            live, xs, lo, hi, gl, al, held = (
                live[keep],
                xs[keep],
                lo[keep],
                hi[keep],
                gl[keep],
                al[keep],
                held[keep],
            )
            if live.size == 0:
                break
        free = ~held
        mask = free[:, :, None] & free[:, None, :]
        lhs = np.where(mask, al, 0.0) + eye * (lam[live, None, None] + held[:, None, :])
        rhs = -np.where(free, gl, 0.0)[:, :, None]
        try:
            step = np.linalg.solve(lhs, rhs)[:, :, 0]
        except np.linalg.LinAlgError:  # lambda below what a singular J^T J needs: the least-norm step
            step = (np.linalg.pinv(lhs) @ rhs)[:, :, 0]
        trial = np.clip(xs + step * x_scale, lo, hi)
        taken = (trial - xs) / x_scale
        r_new, state_new = fun(trial, rows[live])
        nfev[live] += 1
        cost_new = 0.5 * np.einsum("bm,bm->b", r_new, r_new)
        predicted = -(np.einsum("bi,bi->b", gl, taken) + 0.5 * np.einsum("bi,bij,bj->b", taken, al, taken))
        fell = cost[live] - cost_new
        ratio = np.where(predicted > 0, fell / np.where(predicted > 0, predicted, 1.0), -1.0)
        ok = np.isfinite(cost_new) & (fell > 0)
        small_step = np.linalg.norm(taken * x_scale, axis=1) < xtol * (xtol + np.linalg.norm(xs, axis=1))
        small_fall = ok & (fell < ftol * cost[live]) & (ratio > 0.25)
        # accepted steps: new point, residuals and Jacobian
        acc = live[ok]
        if acc.size:
            x[acc], cost[acc] = trial[ok], cost_new[ok]
            js_new = jac(subset(state_new, np.flatnonzero(ok))) * x_scale
            r_ok = r_new[ok]
            a[acc] = np.einsum("bmi,bmj->bij", js_new, js_new)
            g[acc] = np.einsum("bmi,bm->bi", js_new, r_ok)
            rho = ratio[ok]
            lam[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * np.clip(rho, 0.0, 1.0) - 1.0) ** 3)
            nu[acc] = 2.0
        bad = live[~ok]
        lam[bad] *= nu[bad]
        nu[bad] *= 2.0
        stop = small_step | small_fall
        success[live[stop]] = done[live[stop]] = True
        out_of_budget = live[~stop & (nfev[live] >= limit)]
        done[out_of_budget] = True
    return Solution(x, cost, success, nfev)
