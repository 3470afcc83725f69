"""Fit the ball's contact law to CCOR against inbound speed (the founding paper, section 3, Fig. 3).

The model's CCOR at speed v is the COR of the ball (Eq. 1) on a rigid, immovable surface:
`rig.physics.rigid_cor`, solved here for all speeds in one batch. Least squares (scipy
`least_squares`, bounded) fits the variants in VARIANTS; each is scored by leave-one-out error
(leave one ball out when every point names its ball, else one point; in MAX_FOLDS folds
when there are more) and the simplest variant
whose mean squared LOO error lies within one standard error of the best one's is chosen, as
`rig model calibrate` chooses. A variant whose column-scaled Jacobian has a condition number
above MAX_CONDITION, a parameter at a bound, or a standard uncertainty larger than the parameter
itself (MAX_RELATIVE_SIGMA) is not identified.

k1 and c1 enter the rigid-wall CCOR only through one combination (docs/ball.md, "The model's
CCOR"): with a and b also free the data cannot separate them, and `a+b+k1+c1` is never identified
from CCOR alone; it is fitted so that the output says so.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rig.ball.data import CcorPoint
from rig.ball.limits import MAX_FOLDS, MAX_POINTS, MIN_SPEED_RATIO, MIN_SPEEDS, SPEED_GROUP_M_S
from rig.core.errors import RigError
from rig.measure.selection import VariantReport, simplest_within_one_se
from rig.physics import DEFAULT_PARAMS, CollisionParams, Impact, solve_batch

VARIANTS: dict[str, tuple[str, ...]] = {
    "a+b": ("a", "b"),
    "a+b+c1": ("a", "b", "c1"),
    "a+b+k1+c1": ("a", "b", "k1", "c1"),
}
BOUNDS = {"a": (0.0, 1.0), "b": (0.0, 1.0), "k1": (1e4, 1e10), "c1": (0.0, 1e6)}
UNITS = {"m1": "kg", "k1": "N/m^(1+a)", "c1": "N s/m^(1+b)", "a": "", "b": ""}
MAX_CONDITION = 1e8  # of the column-scaled Jacobian, as rig.population.calibrate
FIT_RTOL = 1e-10  # the collision solves inside the fit
DIFF_STEP = 1e-5
MAX_RELATIVE_SIGMA = 1.0  # a fitted constant less certain than its own size is not identified
POOR_RELATIVE_SIGMA = 0.25  # one this uncertain (relative) gets a note
SELECTION = (
    "leave-one-out error (one ball out when every point names its ball, else one point; 50 folds when"
    " there are more); the simplest"
    " identified variant whose mean squared LOO error lies within one standard error of the best one's"
)


class BallFitRefused(RigError):
    """The CCOR data cannot identify the ball's law; the message names the cause."""


def model_ccor(
    params: CollisionParams, speeds: Sequence[float] | np.ndarray, rtol: float = FIT_RTOL
) -> np.ndarray:
    """The model's CCOR (COR on a rigid immovable surface) at each speed, in one batch of solves."""
    v = np.asarray(speeds, dtype=float)
    unique, index = np.unique(v, return_inverse=True)
    cor, _ = solve_batch([Impact(params, float(s)) for s in unique], rtol=rtol)
    return np.asarray(cor, dtype=float)[index]


def speed_levels(speeds: Sequence[float]) -> list[float]:
    """The distinct speeds: sorted, a new one wherever the gap exceeds SPEED_GROUP_M_S."""
    levels: list[list[float]] = []
    for s in sorted(speeds):
        if levels and s - levels[-1][-1] <= SPEED_GROUP_M_S:
            levels[-1].append(s)
        else:
            levels.append([s])
    return [float(np.mean(group)) for group in levels]


@dataclass(frozen=True)
class FitData:
    """The points as arrays: speeds, CCOR, weights (1/u or 1) and the leave-one-out groups."""

    speed: np.ndarray
    ccor: np.ndarray
    weight: np.ndarray
    weighted: bool
    groups: np.ndarray  # group index of each point
    group_names: tuple[str, ...]  # what each leave-out group leaves out (a ball, a point, or a fold)
    by_ball: bool
    n_balls: int  # distinct ball ids (the number of points when the file names no balls)

    @property
    def n(self) -> int:
        """Number of points."""
        return int(self.speed.size)


def fit_data(points: Sequence[CcorPoint]) -> FitData:
    """Check the design and build the arrays; BallFitRefused names the cause."""
    if not points:
        raise BallFitRefused("no CCOR points")
    if len(points) > MAX_POINTS:
        raise BallFitRefused(f"too many points: {len(points)}; a CCOR fit takes at most {MAX_POINTS}")
    speeds = [p.speed_m_s for p in points]
    levels = speed_levels(speeds)
    if len(levels) < MIN_SPEEDS:
        shown = ", ".join(f"{s:.1f}" for s in levels)
        raise BallFitRefused(
            f"too few distinct speeds: {len(levels)} ({shown} m/s); the fit needs at least {MIN_SPEEDS}"
            f" (speeds within {SPEED_GROUP_M_S:g} m/s of each other count as one)"
        )
    ratio = max(speeds) / min(speeds)
    if ratio < MIN_SPEED_RATIO:
        raise BallFitRefused(
            f"speeds span only {min(speeds):.1f}-{max(speeds):.1f} m/s (ratio {ratio:.2f}); a and b need the"
            f" highest at least {MIN_SPEED_RATIO:g} x the lowest (e.g. 25-60 m/s)"
        )
    with_u = [p.u_ccor is not None for p in points]
    if any(with_u) and not all(with_u):
        first = next(p for p in points if p.u_ccor is None)
        raise BallFitRefused(f"u_ccor is given for some points but not all (none at {first.source})")
    weighted = all(with_u)
    weight = np.array([1.0 / p.u_ccor if p.u_ccor else 1.0 for p in points])
    by_ball = all(p.ball_id is not None for p in points) and len({p.ball_id for p in points}) >= 3
    keys = [p.ball_id if by_ball else f"point {i + 1}" for i, p in enumerate(points)]
    names = tuple(dict.fromkeys(str(k) for k in keys))
    index = {name: i for i, name in enumerate(names)}
    groups = np.array([index[str(k)] for k in keys])
    n_balls = len(names) if by_ball else len({p.ball_id for p in points if p.ball_id} or points)
    if len(names) > MAX_FOLDS:  # leave one fold of balls (points) out at a time, not each one
        groups = groups % MAX_FOLDS
        names = tuple(f"fold {i + 1} of {MAX_FOLDS}" for i in range(MAX_FOLDS))
    return FitData(
        speed=np.array(speeds, dtype=float),
        ccor=np.array([p.ccor for p in points], dtype=float),
        weight=weight,
        weighted=weighted,
        groups=groups,
        group_names=names,
        by_ball=by_ball,
        n_balls=n_balls,
    )


@dataclass(frozen=True)
class BallFit:
    """One variant fitted to a set of points."""

    variant: str
    names: tuple[str, ...]
    values: dict[str, float]
    covariance: np.ndarray
    scatter: float  # unweighted RMS of CCOR about the fit, n - p degrees of freedom
    chi2_dof: float  # weighted sum of squares / (n - p) (the scatter squared when unweighted)
    residuals: np.ndarray  # measured - model, CCOR
    condition: float
    dof: int

    def errors(self) -> dict[str, float]:
        """One-sigma uncertainty of each fitted constant."""
        return {n: float(math.sqrt(max(self.covariance[i, i], 0.0))) for i, n in enumerate(self.names)}

    def correlation(self, x: str, y: str) -> float | None:
        """The correlation of two fitted constants (None when either is not fitted or not identified)."""
        if x not in self.names or y not in self.names or not np.all(np.isfinite(self.covariance)):
            return None
        i, j = self.names.index(x), self.names.index(y)
        return float(self.covariance[i, j] / math.sqrt(self.covariance[i, i] * self.covariance[j, j]))


def _scale(name: str, base: CollisionParams) -> float:
    return max(abs(float(getattr(base, name))), 0.1 if name in ("a", "b") else 1.0)


def fit_variant(
    data: FitData,
    variant: str,
    base: CollisionParams = DEFAULT_PARAMS,
    start: Mapping[str, float] | None = None,
    keep: np.ndarray | None = None,
    covariance: bool = True,
) -> BallFit:
    """Weighted least squares of CCOR on the model for one variant (`keep`: a mask of points)."""
    names = VARIANTS[variant]
    mask = np.ones(data.n, dtype=bool) if keep is None else keep
    speed, ccor, w = data.speed[mask], data.ccor[mask], data.weight[mask]
    lo = np.array([BOUNDS[n][0] for n in names])
    hi = np.array([BOUNDS[n][1] for n in names])
    x0 = np.clip([float((start or {}).get(n, getattr(base, n))) for n in names], lo, hi)
    scale = np.array([_scale(n, base) for n in names])

    def params(x: np.ndarray) -> CollisionParams:
        return base.model_copy(update=dict(zip(names, map(float, x), strict=True)))

    def residuals(x: np.ndarray) -> np.ndarray:
        return w * (model_ccor(params(x), speed) - ccor)

    from scipy.optimize import least_squares  # on first use: reading a ball file needs no fit

    tol = 1e-12 if covariance else 1e-8
    res = least_squares(
        residuals, x0, bounds=(lo, hi), jac="2-point", x_scale=scale,
        xtol=tol, ftol=tol, gtol=tol,
        # scipy takes a scalar diff_step (array_like); scipy-stubs accept only a 1-D array
        diff_step=DIFF_STEP,  # type: ignore[arg-type]
    )  # fmt: skip
    values = {n: float(v) for n, v in zip(names, res.x, strict=True)}
    n, p = int(mask.sum()), len(names)
    dof = n - p
    raw = res.fun / w  # model - measured, CCOR
    chi2_dof = float(2.0 * res.cost / dof) if dof > 0 else math.nan
    scatter = float(math.sqrt(np.sum(raw**2) / dof)) if dof > 0 else math.nan
    J = res.jac * scale
    cond = float(np.linalg.cond(J)) if covariance else math.nan
    cov = np.full((p, p), np.nan)
    if covariance and math.isfinite(cond) and cond < MAX_CONDITION and dof > 0:
        # stated u: (J^T W J)^-1, inflated by the Birge ratio when the scatter exceeds them;
        # no u: the residual scatter s^2 (J^T J)^-1
        factor = max(1.0, chi2_dof) if data.weighted else chi2_dof
        # (J^T J)^-1 from the SVD of J: a sum of positive terms, so no negative variance from round-off
        _, sv, vt = np.linalg.svd(J, full_matrices=False)
        cov = factor * (vt.T / sv**2) @ vt * np.outer(scale, scale)
    return BallFit(variant, names, values, cov, scatter, chi2_dof, -raw, cond, dof)


def leave_one_out(data: FitData, full: BallFit, base: CollisionParams = DEFAULT_PARAMS) -> np.ndarray:
    """For each point: measured minus the prediction of a fit without its group (ball or point)."""
    out = np.empty(data.n)
    for g in range(len(data.group_names)):
        out_of = data.groups == g
        fit = fit_variant(data, full.variant, base, start=full.values, keep=~out_of, covariance=False)
        predicted = model_ccor(base.model_copy(update=fit.values), data.speed[out_of])
        out[out_of] = data.ccor[out_of] - predicted
    return out


def _group_mse(data: FitData, errors: np.ndarray) -> np.ndarray:
    return np.array([np.mean(errors[data.groups == g] ** 2) for g in range(len(data.group_names))])


def choose(data: FitData, reports: Mapping[str, VariantReport[BallFit]]) -> str:
    """The variant by the one-SE rule on the groups' (balls' or points') mean squared LOO errors
    (rig.measure.selection), as `rig model calibrate` chooses."""
    return simplest_within_one_se(reports, VARIANTS, lambda errors: _group_mse(data, errors))


@dataclass(frozen=True)
class BallFitResult:
    """Every variant's fit and scores, the chosen one, and the constants held fixed."""

    data: FitData
    base: CollisionParams
    reports: dict[str, VariantReport]
    chosen: str
    notes: tuple[str, ...] = field(default=())

    @property
    def fit(self) -> BallFit:
        """The chosen variant's fit to all the points."""
        return self.reports[self.chosen].fit

    @property
    def params(self) -> CollisionParams:
        """The collision constants with the chosen variant's fitted values."""
        return self.base.model_copy(update=self.fit.values)


def _at_bound(fit: BallFit) -> list[str]:
    out = []
    for n, v in fit.values.items():
        lo, hi = BOUNDS[n]
        if min(v - lo, hi - v) <= 1e-6 * max(hi - lo, 1.0):
            out.append(f"{n} = {v:.4g} at its bound ({lo:g}-{hi:g})")
    return out


def _unidentified(fit: BallFit) -> str:
    """Why a fit does not identify its parameters ('' when it does)."""
    bounded = _at_bound(fit)
    if bounded:
        return "; ".join(bounded)
    if not np.all(np.isfinite(fit.covariance)):
        return (
            f"condition number {fit.condition:.3g} above {MAX_CONDITION:g}:"
            f" the data cannot separate {', '.join(fit.names)}"
        )
    vague = [
        f"{n} = {fit.values[n]:.4g} +- {s:.2g}"
        for n, s in fit.errors().items()
        if not s <= MAX_RELATIVE_SIGMA * abs(fit.values[n])
    ]
    if vague:
        cond = f"condition number {fit.condition:.3g}"
        return f"{', '.join(vague)}: a standard uncertainty larger than the value ({cond})"
    return ""


def fit_ball(
    points: Sequence[CcorPoint],
    base: CollisionParams = DEFAULT_PARAMS,
    variants: Sequence[str] = tuple(VARIANTS),
) -> BallFitResult:
    """Fit every variant, score each by leave-one-out error and choose one.

    BallFitRefused when the design cannot identify a and b or no variant is identified.
    """
    data = fit_data(points)
    reports: dict[str, VariantReport] = {}
    notes: list[str] = []
    whys: dict[str, str] = {}
    start: dict[str, float] = {}
    for name in variants:
        fit = fit_variant(data, name, base, start=start)
        why = _unidentified(fit)
        if why:
            whys[name] = why
            notes.append(f"variant {name}: not identified ({why}); left out")
            reports[name] = VariantReport(fit, np.full(data.n, np.nan), False)
            continue
        start = start or dict(fit.values)  # further variants start at the first identified optimum
        for n, sigma in fit.errors().items():
            if sigma > POOR_RELATIVE_SIGMA * abs(fit.values[n]):
                notes.append(
                    f"variant {name}: {n} = {fit.values[n]:.4g} +- {sigma:.2g} is poorly determined"
                    " (more balls per speed or a wider speed range narrow it)"
                )
        reports[name] = VariantReport(fit, leave_one_out(data, fit, base), True)
    if not any(r.identified for r in reports.values()):
        first = variants[0]
        raise BallFitRefused(f"no variant is identified; {first}: {whys[first]}")
    return BallFitResult(data, base, reports, choose(data, reports), tuple(notes))
