"""The leave-one-out update (rig.population.loo) against the exact refit of every bat it replaces.

The exact refit (exact_leave_one_out, what the calibration still does up to 60 bats) is the
reference: on simulated lab populations of 80 bats (the lab scene's own collision: a location
weight, a bending loss and a per-bat offset the model does not have), the update gives each bat's
leave-one-out error within 2e-5 BBCOR of the refit's (against errors of about 0.006), the LOO RMSE
within 0.5 % and the same chosen variant.
"""

from __future__ import annotations

import numpy as np
import pytest

from rig.measure.selection import VariantReport
from rig.population.calibrate import PAPER_BASE, START, VARIANTS, choose, fit_bats, fit_variant
from rig.population.loo import exact_leave_one_out, leave_one_out
from rig.simulators.scene import Scene
from studies.population.lab import best_scan_location, measured_population
from studies.population.simulated import simulated_population


def lab_rows(n: int, seed: int) -> list:
    rng = np.random.default_rng([seed, 7])
    bats = simulated_population(n, seed)
    return fit_bats(measured_population(Scene.load("lab"), bats, best_scan_location, 0.0037, rng), "bbcor")


@pytest.mark.parametrize("seed", [2, 5])
def test_update_agrees_with_the_exact_refits(seed: int) -> None:
    rows = lab_rows(80, seed)
    fast, exact = {}, {}
    start: dict[str, float] = {}
    for name in VARIANTS:
        fit = fit_variant(rows, name, start={**START, **start})
        if not np.all(np.isfinite(fit.covariance)):
            continue
        start = start or fit.values
        a, b = leave_one_out(rows, fit), exact_leave_one_out(rows, fit)
        assert np.max(np.abs(a - b)) < 2e-5, name
        rmse_a, rmse_b = np.sqrt(np.mean(a**2)), np.sqrt(np.mean(b**2))
        assert rmse_a == pytest.approx(rmse_b, rel=5e-3), name
        fast[name], exact[name] = VariantReport(fit, a, True), VariantReport(fit, b, True)
    assert len(fast) >= 2
    assert choose(fast) == choose(exact)


def test_a_linear_model_gives_the_textbook_leave_one_out() -> None:
    """With no curvature the surrogate is a linear model: its leave-one-out is r_i / (1 - h_ii),
    and each bat's refit of the others by least squares."""
    from rig.population.loo import _surrogate_steps

    rng = np.random.default_rng(3)
    g = rng.normal(size=(30, 2))
    y = rng.normal(size=30)
    beta = np.linalg.lstsq(g, y, rcond=None)[0]
    r = g @ beta - y  # predicted - measured at the optimum
    d = _surrogate_steps(r, g, np.zeros((30, 2, 2)))
    loo = -(r + np.einsum("na,na->n", g, d))  # measured - prediction of the fit to the others
    h = np.einsum("ni,ij,nj->n", g, np.linalg.inv(g.T @ g), g)
    np.testing.assert_allclose(loo, -r / (1 - h), rtol=1e-9, atol=1e-12)
    for i in (0, 7, 29):  # and against refitting the others by least squares
        keep = np.arange(30) != i
        b_i = np.linalg.lstsq(g[keep], y[keep], rcond=None)[0]
        assert loo[i] == pytest.approx(y[i] - g[i] @ b_i, rel=1e-9, abs=1e-12)


@pytest.fixture(scope="module")
def flat_valley() -> tuple[list, object]:
    """62 bats of the sample population's generator, whose m2, c2 and k1_scale trade off: the fit of
    m2+c2+k1_scale lies in a flat valley (where an outside review found the update off by 0.009)."""
    from studies.population.synthetic import synthetic_population

    rows = fit_bats(synthetic_population(26, 36, 2024), "bbcor")
    first = fit_variant(rows, "m2+c2", start=START)
    return rows, fit_variant(rows, "m2+c2+k1_scale", start={**START, **first.values})


def test_in_a_flat_valley_the_untrusted_update_gives_way_to_refits(
    flat_valley: tuple[list, object], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The checked update against exact refits of the bats the unchecked update gets most wrong
    (and two more): equal within 2e-5 there, where the unchecked one misses by more than 1e-3."""
    from rig.population.loo import _refit_error

    rows, fit = flat_valley
    checked = leave_one_out(rows, fit)
    monkeypatch.setattr("rig.population.loo.PROBE_TOL", float("inf"))  # the surrogate trusted blindly
    blind = leave_one_out(rows, fit)
    worst = [int(i) for i in np.argsort(-np.abs(blind - checked))[:6]] + [0, len(rows) - 1]
    exact = np.array([_refit_error(rows, i, fit, PAPER_BASE) for i in worst])
    assert np.max(np.abs(checked[worst] - exact)) < 2e-5
    assert np.max(np.abs(blind[worst] - exact)) > 1e-3


def test_a_bat_whose_leaving_out_lifts_a_parameter_off_its_bound_is_refitted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """100 lab bats whose contact stiffness varies +-35 %: m2+c2+k1_scale holds c2 at its bound 0,
    which the update keeps there; leaving out bat 80 lifts it to ~78 N s/m in a refit (an outside
    review: the unscreened update off by 1.3e-3 there, every other check passed)."""
    from rig.population import loo
    from rig.population.calibrate import _at_bounds
    from studies.population.lab import Variation

    rng = np.random.default_rng([41, 7])
    bats = measured_population(
        Scene.load("lab"),
        simulated_population(100, 41),
        best_scan_location,
        0.0037,
        rng,
        u=0.0046,
        vary=Variation(0.35, 0.0),
    )
    rows = fit_bats(bats, "bbcor")
    first = fit_variant(rows, "m2+c2", start=START)
    fit = fit_variant(rows, "m2+c2+k1_scale", start={**START, **first.values})
    assert [name for name, *_ in _at_bounds(rows, fit)] == ["c2"]
    exact = loo._refit_error(rows, 80, fit, PAPER_BASE)
    assert abs(leave_one_out(rows, fit)[80] - exact) < 5e-5  # the refits' own spread at a bound ~4e-5
    monkeypatch.setattr(loo, "leaves_its_bound", lambda *a: np.zeros(len(rows), dtype=bool))
    assert abs(leave_one_out(rows, fit)[80] - exact) > 1e-3
