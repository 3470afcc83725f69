"""Calibration of the collision model on measured bats: the barrel's m2 and c2, and what else the data need.

The founding paper fits the ball (k1, c1, a, b) to rigid-cylinder tests and validates only the
*normalized* efficiency; the barrel's effective hoop mass m2 and damping c2 are generic values.
Here they are fitted to a population of measured bats (least squares on the chosen metric, each
bat at its own hoop frequency, MOI and impact location, k = m Q^2 / I). Variants add one
parameter each (VARIANTS); the variant is chosen by leave-one-out prediction error with the
one-standard-error rule: the simplest variant whose mean squared LOO error lies within one
standard error (of the paired difference) of the best one's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.errors import RigError
from rig.core.units import INCH
from rig.measure.metrics import compute_metrics
from rig.measure.selection import VariantReport, simplest_within_one_se
from rig.physics import DEFAULT_PARAMS, CollisionParams, PivotedBat
from rig.physics.bat_batch import pivoted_cor_sets
from rig.population.budget import MAX_EVALUATIONS, Budget
from rig.population.dataset import METRICS, PopulationBat, missing_column
from rig.population.limits import DEFAULT_LOCATION_IN, MIN_BATS, MIN_HOOP_SPAN_HZ
from rig.population.model import BALL_MASS_KG, SPEED_M_S

WARM_START_BATS = 100  # above twice this, the first variant starts from its fit to this many bats
EXACT_LOO_UP_TO = 60  # bats: up to this many, leave-one-out refits each bat (O(n^2), as before)
MAX_CONDITION = 1e8  # of the column-scaled Jacobian; above it a parameter is not identified
DIFF_STEP = 1e-5  # relative step of the finite-difference Jacobian
FIT_RTOL = 1e-9  # the collision solves inside the fit: far below any bat-to-bat scatter
START = {"m2": DEFAULT_PARAMS.m2, "c2": DEFAULT_PARAMS.c2, "k1_scale": 1.0, "offset": 0.0}
BOUNDS = {"m2": (1e-3, 1.0), "c2": (0.0, 1e5), "k1_scale": (0.1, 10.0), "offset": (-0.3, 0.3)}
UNITS = {"m2": "kg", "c2": "N s/m", "k1_scale": "", "offset": "(metric)"}
VARIANTS: dict[str, tuple[str, ...]] = {
    "m2+c2": ("m2", "c2"),
    "m2+c2+k1_scale": ("m2", "c2", "k1_scale"),
    "m2+c2+offset": ("m2", "c2", "offset"),
}


class CalibrationRefused(RigError):
    """The data cannot identify the model's parameters; the message names the cause."""


@dataclass(frozen=True)
class FitBat:
    """What the fit needs of one bat: the metric = alpha + beta e_A (rig.measure.metrics)."""

    bat_id: str
    hoop_hz: float
    pivoted: PivotedBat
    alpha: float
    beta: float
    measured: float
    length_in: float = math.nan  # the bat's length and where it was struck, kept for the record
    location_in: float = math.nan
    speed_m_s: float = SPEED_M_S  # the inbound speed its collision is solved at (the standard's)


def fitted_quantity(metric: str) -> str:
    """What a calibration of `metric` fits: the metric itself where the population has its column
    (bbcor, besr, bbs), else the runs' BBCOR (a BPF, a USA Softball BBS), the same e_A mapped by
    another line per bat, from which the cross-check predicts the metric."""
    return metric if metric in METRICS else "bbcor"


def metric_line(
    metric: str,
    q: float,
    moi: float,
    length_m: float,
    *,
    ball_mass_kg: float = BALL_MASS_KG,
    ball_cor: float | None = None,
) -> tuple[float, float]:
    """alpha, beta with metric = alpha + beta e_A, from the rig's own metric code at e_A = 0 and 1
    (`ball_cor`: the run's ball COR, which a BPF divides by)."""
    args = (q, moi, ball_mass_kg, length_m)
    m0 = compute_metrics(SPEED_M_S, 0.0, *args, ball_cor=ball_cor).value(metric)
    m1 = compute_metrics(SPEED_M_S, SPEED_M_S, *args, ball_cor=ball_cor).value(metric)
    return m0, m1 - m0


def fit_bats(
    bats: Sequence[PopulationBat],
    metric: str,
    speed_m_s: float = SPEED_M_S,
    ball_mass_kg: float = BALL_MASS_KG,
) -> list[FitBat]:
    """Check the rows the fit needs; CalibrationRefused names the first missing value.

    `metric` is what is fitted (a population column: fitted_quantity's)."""
    if metric not in METRICS:
        raise CalibrationRefused(f"unknown metric {metric!r}; known: {', '.join(METRICS)}")
    missing = missing_column(bats, ("moi_kgm2", "length_in", metric))
    if missing:
        raise CalibrationRefused(f"{missing}; the fit needs hoop_hz, moi_kgm2, length_in and {metric}")
    out = []
    for b in bats:
        assert b.moi_kgm2 is not None and b.length_in is not None
        location = DEFAULT_LOCATION_IN if b.location_in is None else b.location_in
        q = (b.length_in - location) * INCH - PIVOT_FROM_KNOB_M
        if q <= 0.05:
            raise CalibrationRefused(f"bat {b.bat_id}: impact {location:g} in from the end is off the barrel")
        alpha, beta = metric_line(metric, q, b.moi_kgm2, b.length_in * INCH, ball_mass_kg=ball_mass_kg)
        value = b.metric(metric)
        assert value is not None
        out.append(
            FitBat(
                b.bat_id,
                b.hoop_hz,
                PivotedBat(moi_kgm2=b.moi_kgm2, impact_from_pivot_m=q),
                alpha,
                beta,
                value,
                b.length_in,
                location,
                speed_m_s,
            )
        )
    return out


# the ball the calibration solves with unless a fitted ball (BALL.json, `--ball`) replaces it:
# the paper's constants, m1 the rig's ball
PAPER_BASE = DEFAULT_PARAMS.model_copy(update={"m1": BALL_MASS_KG})


def model_params(values: dict[str, float], base: CollisionParams = PAPER_BASE) -> CollisionParams:
    """The collision constants for fitted values: the ball's from `base` (k1 times any k1_scale)."""
    update = {"m2": values.get("m2", base.m2), "c2": values.get("c2", base.c2)}
    update["k1"] = base.k1 * values.get("k1_scale", 1.0)
    return base.model_copy(update=update)


def predict_many(
    bats: Sequence[FitBat],
    sets: Sequence[dict[str, float]],
    rtol: float = FIT_RTOL,
    base: CollisionParams = PAPER_BASE,
    numpy_lanes: bool = False,
) -> np.ndarray:
    """The metric predicted for each bat (columns) under each set of values (rows): one batch of solves.

    numpy_lanes: a few hundred solves run in numpy, without loading numba (`fast.solve_batch`).
    """
    hoops = np.array([b.hoop_hz for b in bats])
    eff = np.array([b.pivoted.effective_mass for b in bats])
    alpha = np.array([b.alpha for b in bats])
    beta = np.array([b.beta for b in bats])
    params = [model_params(values, base) for values in sets]
    speed = bats[0].speed_m_s if bats else SPEED_M_S  # one calibration, one speed
    e_a, _ = pivoted_cor_sets(params, speed, hoops, eff, rtol, numpy_lanes)
    offsets = np.array([values.get("offset", 0.0) for values in sets])
    return alpha + beta * e_a + offsets[:, None]


def predict(
    bats: Sequence[FitBat],
    values: dict[str, float],
    rtol: float = FIT_RTOL,
    base: CollisionParams = PAPER_BASE,
) -> np.ndarray:
    """The metric the model predicts for each bat, in one batch of compiled solves."""
    return predict_many(bats, [values], rtol, base)[0]


@dataclass(frozen=True)
class Fit:
    """One variant fitted to a set of bats."""

    variant: str
    names: tuple[str, ...]
    values: dict[str, float]
    covariance: np.ndarray  # s^2 (J^T J)^-1, in the parameters' own units
    scatter: float  # sqrt(SSR / (n - p)): bat-to-bat scatter the model leaves
    residuals: np.ndarray
    condition: float
    converged: bool = True
    evaluations: int = 0

    def errors(self) -> dict[str, float]:
        """One-sigma uncertainty of each parameter."""
        return {n: float(math.sqrt(self.covariance[i, i])) for i, n in enumerate(self.names)}


def _upper(bats: Sequence[FitBat], name: str) -> float:
    hi = BOUNDS[name][1]
    if name == "m2":  # the hoop mass is part of the bat: below I/Q^2 of every bat
        hi = min(hi, 0.95 * min(b.pivoted.effective_mass for b in bats))
    return hi


def fit_variant(
    bats: Sequence[FitBat],
    variant: str,
    start: dict[str, float] | None = None,
    covariance: bool = True,
    base: CollisionParams = PAPER_BASE,
    budget: Budget | None = None,
) -> Fit:
    """Least squares of the measured metric on the model's prediction for one variant.

    Each model evaluation ticks `budget` (CalibrationStopped past its time limit); a fit stops
    after MAX_EVALUATIONS evaluations, `converged` False.
    """
    names = VARIANTS[variant]
    measured = np.array([b.measured for b in bats])
    lo = np.array([BOUNDS[n][0] for n in names])
    hi = np.array([_upper(bats, n) for n in names])
    x0 = np.clip([(start or START).get(n, START[n]) for n in names], lo, hi)
    scale = np.array([max(abs(START[n]), 1e-2) for n in names])

    def residuals(x: np.ndarray) -> np.ndarray:
        if budget is not None:
            budget.tick()
        return predict(bats, dict(zip(names, x, strict=True)), base=base) - measured

    tol = 1e-10 if covariance else 1e-7  # a leave-one-out refit starts at the full fit's optimum
    from scipy.optimize import least_squares  # on first use: reading a calibration needs no fit

    res = least_squares(
        residuals,
        x0,
        bounds=(lo, hi),
        jac="2-point",
        # scipy takes a scalar diff_step (array_like); scipy-stubs accept only a 1-D array
        diff_step=DIFF_STEP,  # type: ignore[arg-type]
        x_scale=scale,
        xtol=tol,
        ftol=tol * 1e-2,
        gtol=tol * 1e-2,
        max_nfev=MAX_EVALUATIONS,
    )
    values = {n: float(v) for n, v in zip(names, res.x, strict=True)}
    n, p = len(bats), len(names)
    scatter = float(math.sqrt(2.0 * res.cost / (n - p))) if n > p else float("nan")
    J = res.jac * scale  # columns per unit of each parameter's scale
    cond = float(np.linalg.cond(J)) if covariance else float("nan")
    cov = np.full((p, p), np.nan)
    if covariance and math.isfinite(cond) and cond < MAX_CONDITION:
        cov = scatter**2 * np.linalg.inv(J.T @ J) * np.outer(scale, scale)
    return Fit(variant, names, values, cov, scatter, res.fun.copy(), cond, int(res.status) > 0, int(res.nfev))


def leave_one_out(
    bats: Sequence[FitBat], full: Fit, base: CollisionParams = PAPER_BASE, budget: Budget | None = None
) -> np.ndarray:
    """For each bat: its measured value minus the prediction of a fit to the others.

    Up to EXACT_LOO_UP_TO bats, a refit per bat (the reference, as before); above, the fit to all
    bats updated per bat (rig.population.loo), linear in the number of bats.
    """
    from rig.population import loo  # it builds on this module's fit

    if len(bats) <= EXACT_LOO_UP_TO:
        return loo.exact_leave_one_out(bats, full, base, budget)
    return loo.leave_one_out(bats, full, base, budget)


def choose(reports: dict[str, VariantReport[Fit]]) -> str:
    """The variant by the one-SE rule on the bats' leave-one-out errors (rig.measure.selection)."""
    return simplest_within_one_se(reports, VARIANTS, np.square)


@dataclass(frozen=True)
class Calibration:
    """The chosen variant, every variant's scores, and the data it came from."""

    metric: str
    bats: tuple[FitBat, ...]
    reports: dict[str, VariantReport]
    chosen: str
    notes: tuple[str, ...] = field(default=())
    base: CollisionParams = PAPER_BASE  # the ball's constants the fit solved with
    speed_m_s: float = SPEED_M_S  # the inbound speed the collisions were solved at

    @property
    def fitted(self) -> str:
        """The quantity the bats' measured values are (fitted_quantity of the metric)."""
        return fitted_quantity(self.metric)

    @property
    def fit(self) -> Fit:
        """The chosen variant's fit to all the bats."""
        return self.reports[self.chosen].fit


def check_identifiable(bats: Sequence[FitBat]) -> None:
    """CalibrationRefused when too few bats or too narrow a hoop range can identify m2 and c2."""
    if len(bats) < MIN_BATS:
        raise CalibrationRefused(f"too few bats: {len(bats)}; the fit needs at least {MIN_BATS}")
    hoops = [b.hoop_hz for b in bats]
    span = max(hoops) - min(hoops)
    if span < MIN_HOOP_SPAN_HZ:
        raise CalibrationRefused(
            f"hoop frequencies span only {span:.0f} Hz ({min(hoops):.0f}-{max(hoops):.0f} Hz);"
            f" m2 and c2 need at least {MIN_HOOP_SPAN_HZ:.0f} Hz"
        )


def _at_bounds(bats: Sequence[FitBat], fit: Fit) -> list[tuple[str, float, float, float]]:
    """(name, value, lower, upper) of each parameter of a fit that sits at a bound."""
    out = []
    for n, v in fit.values.items():
        lo, hi = BOUNDS[n][0], _upper(bats, n)
        if min(v - lo, hi - v) <= 1e-6 * max(abs(hi - lo), 1.0):
            out.append((n, v, lo, hi))
    return out


def calibrate(
    bats: Sequence[PopulationBat],
    metric: str = "bbcor",
    variants: Sequence[str] = tuple(VARIANTS),
    base: CollisionParams = PAPER_BASE,
    budget: Budget | None = None,
    speed_m_s: float = SPEED_M_S,
) -> Calibration:
    """Fit every variant, check the residuals for structure, score each variant by leave-one-out
    prediction error, choose one.

    `base` gives the ball's constants (m1, k1, c1, a, b: the paper's, or a fitted ball's);
    `budget` the time limit and the progress sink (CalibrationStopped past the limit);
    `speed_m_s` the inbound speed of the metric's standard (base.m1 its ball's mass). A metric
    without a population column (a BPF, a USA Softball BBS) fits the runs' BBCOR (fitted_quantity).
    """
    from rig.population.structure import MIN_BATS as STRUCTURE_MIN_BATS  # scipy.special: on first use
    from rig.population.structure import check_structure

    budget = budget or Budget()
    rows = fit_bats(bats, fitted_quantity(metric), speed_m_s, base.m1)
    check_identifiable(rows)
    reports, notes = {}, []
    start: dict[str, float] = {}
    for name in variants:
        # each further variant starts from the first identified one's optimum (its extra parameter
        # neutral), so it fits at least as well in sample and cannot stall in a worse local minimum
        budget.say(f"fitting {name} to {len(rows)} bats")
        x0 = {**START, **start}
        if not start and len(rows) > 2 * WARM_START_BATS:  # the long way from the paper's values on a few
            every = len(rows) / WARM_START_BATS
            few = [rows[int(k * every)] for k in range(WARM_START_BATS)]
            x0.update(fit_variant(few, name, start=x0, covariance=False, base=base, budget=budget).values)
        fit = fit_variant(rows, name, start=x0, base=base, budget=budget)
        identified = bool(np.all(np.isfinite(fit.covariance)))
        bounded = _at_bounds(rows, fit)
        budget.say(
            f"fitted {name}",
            f"{name}: {fit.evaluations} evaluations, scatter {fit.scatter:.4g}"
            + ("" if fit.converged else ", not converged")
            + ("" if identified else ", not identified"),
        )
        if not fit.converged:
            notes.append(f"variant {name}: not converged in {MAX_EVALUATIONS} model evaluations; left out")
            reports[name] = VariantReport(fit, np.full(len(rows), np.nan), False)
            continue
        if not identified:
            why = ", ".join(f"{n} = {v:.4g} at its bound" for n, v, _, _ in bounded)
            notes.append(
                f"variant {name}: not identified (condition number {fit.condition:.3g}:"
                f" {why or 'the data cannot separate ' + ', '.join(fit.names)}); left out"
            )
            reports[name] = VariantReport(fit, np.full(len(rows), np.nan), False)
            continue
        start = start or fit.values
        for n, v, lo, hi in bounded:
            notes.append(
                f"variant {name}: {n} = {v:.4g} at its bound ({lo:g}-{hi:.4g}); its sigma is unreliable"
            )
        reports[name] = VariantReport(fit, np.full(len(rows), np.nan), True)
    fitted = [r.fit for r in reports.values() if r.identified]
    if not fitted:
        first = reports[variants[0]].fit
        if not first.converged:
            raise CalibrationRefused(
                f"no variant converged in {MAX_EVALUATIONS} model evaluations: the model family does not"
                " settle on these data"
            )
        raise CalibrationRefused(
            f"singular Jacobian: the data cannot separate {', '.join(first.names)}"
            f" (condition number {first.condition:.3g}); no variant is identified"
        )
    best = min(fitted, key=lambda f: f.scatter)  # the family's best description of the bats
    check_structure([b.hoop_hz for b in rows], best.residuals.tolist(), best.variant)
    if len(rows) < STRUCTURE_MIN_BATS:
        notes.append(
            f"the residual-structure check (a trend with hoop frequency, two groups of bats) needs"
            f" {STRUCTURE_MIN_BATS} bats; with {len(rows)} it was not made"
        )
    for name, report in list(reports.items()):
        if report.identified:
            budget.say(f"leave-one-out of {name} on {len(rows)} bats")
            reports[name] = VariantReport(report.fit, leave_one_out(rows, report.fit, base, budget), True)
    budget.say("done", f"done: {budget.evaluations} model evaluations")
    return Calibration(metric, tuple(rows), reports, choose(reports), tuple(notes), base, speed_m_s)
