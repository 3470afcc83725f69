"""Leave-one-out prediction errors of a fitted variant without refitting it once per bat.

Refitting every variant to the n - 1 other bats for each of n bats costs O(n^2) solves. Instead,
each bat's prediction is expanded to second order about the fit to all bats (residual r_k,
gradient g_k and Hessian H_k in the parameters, by differences: 2p + p(p - 1)/2 batches of n
solves), and the fit to all bats but i minimises that quadratic surrogate,

    d_i = argmin_d  sum over k != i of (r_k + g_k d + d H_k d / 2)^2,

by Gauss-Newton steps whose sums over k are moments of all bats computed once, less bat i's own
term: O(n p^4) in all. Bat i is then predicted at x + d_i with the model itself (n solves in one
batch). For a linear model this is the exact leave-one-out, r_i / (1 - h_ii); for ours it is exact
to second order in how far one bat moves the parameters, which shrinks as 1/n. Parameters at a
bound stay there. A bat of leverage h_ii above MAX_LEVERAGE is refitted exactly.

The surrogate is trusted only where it is checked (`trusted`): at the longest steps it takes, the
quadratic models of every bat must give the model's own predictions within PROBE_TOL, and at each
bat's own step its quadratic model must give the prediction made there. In a flat valley of a
variant (parameters that trade off, as m2, c2 and k1_scale can on one-construction populations) the
quadratic models fail far from the fit and the surrogate's steps run away (an outside review found
LOO errors off by 0.009 and the chosen variant changed): a bat whose own check fails is refitted
exactly, every bat if a check at the MAX_PROBES longest steps fails. A parameter the full fit holds
at a bound stays there in the update, so a bat whose leaving-out may lift it off (`leaves_its_bound`:
it takes away half or more of the slope that holds the parameter there) is refitted too.
`exact_leave_one_out` is the refit of every bat: what the
calibration does up to EXACT_LOO_UP_TO bats, and the reference the update is tested against
(tests/population/test_loo.py).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rig.physics import CollisionParams, solve_batch
from rig.physics.bat import impact_for
from rig.population.budget import Budget
from rig.population.calibrate import (
    BOUNDS,
    FIT_RTOL,
    PAPER_BASE,
    START,
    Fit,
    FitBat,
    _at_bounds,
    _upper,
    fit_variant,
    model_params,
    predict,
    predict_many,
)

FD_STEP = 1e-2  # of each parameter's scale (START, at least 0.01): the derivatives' central differences
MAX_LEVERAGE = 0.5  # above it a bat is refitted exactly
SURROGATE_STEPS = 20  # Gauss-Newton steps on the quadratic surrogate (it converges in a few)
PROBE_TOL = 1e-5  # metric units: the quadratic models' largest miss allowed (LOO errors ~ 0.006)
MAX_PROBES = 4  # steps the surrogate is checked at, the longest (one batch of n solves each)


def predict_pairs(
    bats: Sequence[FitBat], sets: Sequence[dict[str, float]], base: CollisionParams = PAPER_BASE
) -> np.ndarray:
    """The metric predicted for bat i under set i: one batch of len(bats) solves."""
    impacts = [
        impact_for(model_params(v, base), b.speed_m_s, b.hoop_hz, b.pivoted)
        for b, v in zip(bats, sets, strict=True)
    ]
    e_a, _ = solve_batch(impacts, rtol=FIT_RTOL)
    alpha = np.array([b.alpha for b in bats])
    beta = np.array([b.beta for b in bats])
    return alpha + beta * e_a + np.array([v.get("offset", 0.0) for v in sets])


def _scale(name: str) -> float:
    return max(abs(START[name]), 1e-2)


def derivatives(
    bats: Sequence[FitBat], fit: Fit, free: Sequence[str], base: CollisionParams = PAPER_BASE
) -> tuple[np.ndarray, np.ndarray]:
    """Gradient (n, p) and Hessian (n, p, p) of each bat's prediction in the free parameters, per
    unit of each parameter's scale, by central differences of the model's own prediction."""
    p = len(free)
    h = np.full(p, FD_STEP)
    for a, n in enumerate(free):  # keep the stencil inside the bounds
        x, lo, hi = fit.values[n] / _scale(n), BOUNDS[n][0] / _scale(n), _upper(bats, n) / _scale(n)
        h[a] = min(FD_STEP, 0.5 * (x - lo), 0.5 * (hi - x))
    offsets: list[tuple[int, ...]] = []
    for a in range(p):
        offsets += [(a, 1), (a, -1)]
    for a in range(p):
        for b in range(a + 1, p):
            offsets.append((a, 1, b, 1))
    sets = []
    for off in offsets:
        values = dict(fit.values)
        for k in range(0, len(off), 2):
            n = free[off[k]]
            values[n] = fit.values[n] + off[k + 1] * h[off[k]] * _scale(n)
        sets.append(values)
    f = predict_many(bats, sets, base=base) if sets else np.zeros((0, len(bats)))
    f0 = np.array([b.measured for b in bats]) + np.asarray(fit.residuals)
    grad = np.empty((len(bats), p))
    hess = np.empty((len(bats), p, p))
    for a in range(p):
        up, down = f[2 * a], f[2 * a + 1]
        grad[:, a] = (up - down) / (2 * h[a])
        hess[:, a, a] = (up - 2 * f0 + down) / h[a] ** 2
    row = 2 * p
    for a in range(p):
        for b in range(a + 1, p):  # one more solve per pair: first order in h, which the surrogate bears
            hess[:, a, b] = hess[:, b, a] = (f[row] - f[2 * a] - f[2 * b] + f0) / (h[a] * h[b])
            row += 1
    return grad, hess


def _surrogate_steps(r: np.ndarray, g: np.ndarray, hs: np.ndarray) -> np.ndarray:
    """For each bat i: the step d minimising sum over k != i of (r_k + g_k d + d H_k d / 2)^2.

    Gauss-Newton on the quadratic surrogate; the sums over all bats are moments computed once
    (O(n p^4)), bat i's own term taken off, so that every bat costs O(p^4), not O(n).
    """
    s_jj = np.einsum("ka,kb->ab", g, g)
    s_jr = g.T @ r
    s_hr = np.einsum("kab,k->ab", hs, r)
    s_jh = np.einsum("ka,kbc->abc", g, hs)
    s_hh = np.einsum("kab,kcd->abcd", hs, hs)
    n, p = g.shape
    d = np.zeros((n, p))
    for _ in range(SURROGATE_STEPS):
        # all bats' sums at each bat's d ...
        mm = (
            s_jj[None]
            + np.einsum("acd,nd->nac", s_jh, d)
            + np.einsum("cab,nb->nac", s_jh, d)
            + np.einsum("abcd,nb,nd->nac", s_hh, d, d)
        )
        mr = (
            s_jr[None]
            + d @ s_jj.T
            + 0.5 * np.einsum("abc,nb,nc->na", s_jh, d, d)
            + d @ s_hr.T
            + np.einsum("eab,nb,ne->na", s_jh, d, d)
            + 0.5 * np.einsum("abcd,nb,nc,nd->na", s_hh, d, d, d)
        )
        # ... less bat i's own term
        m_i = g + np.einsum("nab,nb->na", hs, d)
        r_i = r + np.einsum("na,na->n", g, d) + 0.5 * np.einsum("na,nab,nb->n", d, hs, d)
        mm -= np.einsum("na,nc->nac", m_i, m_i)
        mr -= m_i * r_i[:, None]
        step = np.linalg.solve(mm, mr[:, :, None])[:, :, 0]
        d = d - step
        if np.max(np.abs(step)) < 1e-12:
            break
    return d


def leave_one_out(
    bats: Sequence[FitBat], full: Fit, base: CollisionParams = PAPER_BASE, budget: Budget | None = None
) -> np.ndarray:
    """For each bat: its measured value minus the prediction of the fit to the others (updated)."""
    pinned = {n for n, *_ in _at_bounds(bats, full)}
    free = [n for n in full.names if n not in pinned]
    r = np.asarray(full.residuals, dtype=float)
    measured = np.array([b.measured for b in bats])
    if not free:  # every parameter pinned at a bound: the fit to the others is the same fit
        return -r
    if budget is not None:
        budget.tick()
    g, hs = derivatives(bats, full, free, base)
    lev = np.einsum("ni,ij,nj->n", g, np.linalg.pinv(g.T @ g), g)
    exact = lev > MAX_LEVERAGE
    d = _surrogate_steps(r, g, hs)
    scale = np.array([_scale(n) for n in free])
    x = np.array([full.values[n] for n in free])
    lo = np.array([BOUNDS[n][0] for n in free])
    hi = np.array([_upper(bats, n) for n in free])
    moved = np.clip(x[None, :] + d * scale, lo, hi)
    steps = (moved - x[None, :]) / scale  # as taken: inside the bounds
    sets = [{**full.values, **dict(zip(free, row, strict=True))} for row in moved]
    predicted = predict_pairs(bats, sets, base)
    out = measured - predicted
    f0 = measured + r  # each bat's prediction at the fit
    own = np.abs(predicted - _quadratic(f0, g, hs, steps))  # each bat's model at its own step
    untrusted = own > PROBE_TOL
    if not trusted(bats, sets, base, f0, g, hs, steps, budget):
        untrusted[:] = True
    untrusted |= leaves_its_bound(bats, full, base, f0, g, steps)
    if budget is not None and (exact | untrusted).any():
        budget.say(
            budget.doing,
            f"{budget.doing}: refitting {int((exact | untrusted).sum())} bats exactly ({int(exact.sum())}"
            f" of leverage above {MAX_LEVERAGE}, {int(untrusted.sum())} where the update is not trusted:"
            f" its surrogate misses the model by more than {PROBE_TOL:g}, or a parameter at its bound"
            " may leave it)",
        )
    exact |= untrusted
    refits = np.flatnonzero(exact)
    every = max(1, len(refits) // 10)
    for done, i in enumerate(refits):
        if budget is not None and done and done % every == 0:
            budget.say(budget.doing, f"{budget.doing}: refitted {done} of {len(refits)} bats")
        out[i] = _refit_error(bats, int(i), full, base, budget)
    return out


def _quadratic(f0: np.ndarray, g: np.ndarray, hs: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Bat k's second-order prediction at steps[k] (f0: its prediction at the fit)."""
    return f0 + np.einsum("na,na->n", g, steps) + 0.5 * np.einsum("na,nab,nb->n", steps, hs, steps)


def trusted(
    bats: Sequence[FitBat],
    sets: Sequence[dict[str, float]],
    base: CollisionParams,
    f0: np.ndarray,
    g: np.ndarray,
    hs: np.ndarray,
    steps: np.ndarray,
    budget: Budget | None = None,
) -> bool:
    """Whether the surrogate may be trusted (`sets[i]`: the parameters at bat i's step, `steps[i]`
    in scaled units): at its MAX_PROBES longest steps, every bat's quadratic
    model against the model's prediction there (one batch of n solves each), all within PROBE_TOL.
    One miss and no step is trusted, short ones included: in a flat valley a bat's true step can
    lie beyond where the surrogate holds while the surrogate's own step stays short (trusting the
    steps shorter than a miss left one of 62 sample bats off by 5.6e-3)."""
    size = np.max(np.abs(steps), axis=1)
    for i in np.argsort(-size, kind="stable")[:MAX_PROBES]:
        if budget is not None:
            budget.tick()
        model = predict_pairs(bats, [sets[i]] * len(bats), base)
        step = np.broadcast_to(steps[i], steps.shape)
        if np.max(np.abs(model - _quadratic(f0, g, hs, step))) > PROBE_TOL:
            return False
    return True


def leaves_its_bound(
    bats: Sequence[FitBat], full: Fit, base: CollisionParams, f0: np.ndarray, g: np.ndarray, d: np.ndarray
) -> np.ndarray:
    """Bats whose leaving-out may lift a parameter the full fit holds at a bound off it: the update
    keeps it there, a refit need not (an outside review: c2 at 0 moved to 78 N s/m, the bat's LOO
    error off by 1.3e-3, every other check passed). For each such parameter q the slope of the
    others' sum of squares in q, to first order at the bat's updated step (a_k = d f_k / dq, one
    batch of n solves a step into the bounds), is what holds q at its bound: a bat that takes away
    half of it or more is refitted (f0: each bat's prediction at the fit, d: its step)."""
    out = np.zeros(len(bats), dtype=bool)
    r = f0 - np.array([b.measured for b in bats])  # the fit's residuals
    r_i = r + np.einsum("na,na->n", g, d)  # each bat's residual at its updated step
    for name, value, lo, hi in _at_bounds(bats, full):
        inward = 1.0 if value - lo <= hi - value else -1.0  # the direction into the allowed range
        h = inward * FD_STEP * _scale(name)
        moved = predict_pairs(bats, [{**full.values, name: value + h}] * len(bats), base)
        a = (moved - f0) / h * inward  # slope inward, per unit
        hold = float(r @ a)  # >= 0 at a bound the fit presses on
        held = hold + d @ (g.T @ a) - r_i * a  # the others' slope at bat i's step
        out |= held <= 0.5 * hold
    return out


def _refit_error(
    bats: Sequence[FitBat], i: int, full: Fit, base: CollisionParams, budget: Budget | None = None
) -> float:
    """Bat i's measured value minus the prediction of a refit to the other bats."""
    rest = [b for j, b in enumerate(bats) if j != i]
    fit = fit_variant(rest, full.variant, start=full.values, covariance=False, base=base, budget=budget)
    return bats[i].measured - float(predict([bats[i]], fit.values, base=base)[0])


def exact_leave_one_out(
    bats: Sequence[FitBat],
    full: Fit,
    base: CollisionParams = PAPER_BASE,
    budget: Budget | None = None,
) -> np.ndarray:
    """The reference: a refit to the other bats for every bat (n fits, O(n^2) solves)."""
    return np.array([_refit_error(bats, i, full, base, budget) for i in range(len(bats))])
