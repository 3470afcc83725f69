"""The ball-law fit against CCOR data from the tests' own reference solver (tests/ball/reference_ccor.py).

Recovery of known a and b within 2 sigma, the stated sigma's honesty over 20 seeds, the exact
k1-c1 degeneracy of the rigid-wall CCOR (why `a+b+k1+c1` is never identified), the design refusals.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.ball.data import CcorPoint
from rig.ball.fit import BallFitRefused, fit_ball, fit_data, fit_variant, model_ccor, speed_levels
from rig.physics import DEFAULT_PARAMS
from tests.ball.reference_ccor import PAPER, reference_ccor
from tests.ball.synthetic import SPEEDS, TRUE, ccor_points, true_ccor

SEEDS = 20


def test_rig_model_ccor_agrees_with_the_reference_solver() -> None:
    params = DEFAULT_PARAMS.model_copy(update={"a": TRUE["a"], "b": TRUE["b"]})
    ours = model_ccor(params, SPEEDS)
    theirs = [true_ccor(v) for v in SPEEDS]
    assert np.max(np.abs(ours - theirs)) < 1e-8


@settings(max_examples=6, deadline=None)
@given(st.floats(1.5, 8.0), st.sampled_from([25.0, 60.0]))
def test_k1_and_c1_enter_ccor_only_through_one_combination(scale: float, speed: float) -> None:
    """k1 -> s k1 with c1 -> s^((1+b)/(2+a)) c1 leaves CCOR unchanged (the model's scaling law), while
    k1 alone moves it: CCOR cannot separate k1 from c1."""
    q = (1.0 + PAPER["b"]) / (2.0 + PAPER["a"])
    moved = {**PAPER, "k1": PAPER["k1"] * scale, "c1": PAPER["c1"] * scale**q}
    assert reference_ccor(speed, **moved) == pytest.approx(reference_ccor(speed, **PAPER), abs=1e-9)
    assert (
        abs(reference_ccor(speed, **{**PAPER, "k1": PAPER["k1"] * scale}) - reference_ccor(speed, **PAPER))
        > 0.01
    )


def test_recovers_a_and_b_within_two_sigma_and_says_which_variant() -> None:
    result = fit_ball(ccor_points(seed=0))
    assert result.chosen == "a+b"
    fit = result.fit
    sig = fit.errors()
    for n in ("a", "b"):
        assert abs(fit.values[n] - TRUE[n]) <= 2.0 * sig[n], (n, fit.values[n], sig[n])
    corr = fit.correlation("a", "b")
    assert corr is not None and corr > 0.99  # a and b trade off along one line (docs/ball.md)
    assert not result.reports["a+b+k1+c1"].identified
    assert math.isfinite(result.reports["a+b"].loo_rmse)
    assert result.fit.scatter == pytest.approx(5e-4, rel=0.5)


def test_stated_sigma_is_honest_over_twenty_seeds() -> None:
    """Within 2 sigma on at least 15 of 20 seeds for each of a and b: the nominal 2-sigma coverage with
    18 degrees of freedom is 94 %, and fewer than 15 of 20 then happens less than once in 100 draws;
    sigma understated by half would give about 68 % (13-14 of 20)."""
    inside = {"a": 0, "b": 0}
    for seed in range(SEEDS):
        fit = fit_variant(fit_data(ccor_points(seed=100 + seed)), "a+b")
        for n, s in fit.errors().items():
            inside[n] += abs(fit.values[n] - TRUE[n]) <= 2.0 * s
    print(f"coverage within 2 sigma over {SEEDS} seeds: {inside}")
    assert inside["a"] >= 15 and inside["b"] >= 15, inside


def test_stated_u_are_used_as_weights_and_inflated_when_the_scatter_exceeds_them() -> None:
    pts = ccor_points(seed=3, with_u=True)
    honest = fit_variant(fit_data(pts), "a+b")
    understated = [CcorPoint(p.speed_m_s, p.ccor, 0.1 * (p.u_ccor or 0.0), p.ball_id) for p in pts]
    fit = fit_variant(fit_data(understated), "a+b")
    unweighted = fit_variant(fit_data(ccor_points(seed=3)), "a+b")
    # the same estimate; sigma from the scatter (Birge ratio), not from the understated u
    assert fit.values["a"] == pytest.approx(honest.values["a"], rel=1e-6)
    assert fit.errors()["a"] == pytest.approx(unweighted.errors()["a"], rel=1e-3)


def test_leave_one_ball_out_when_balls_are_named() -> None:
    data = fit_data(ccor_points(seed=1))
    assert data.by_ball and len(data.group_names) == 20
    anonymous = fit_data([CcorPoint(p.speed_m_s, p.ccor) for p in ccor_points(seed=1)])
    assert not anonymous.by_ball


def test_speeds_within_a_metre_per_second_count_as_one() -> None:
    assert len(speed_levels([25.0, 25.3, 25.9, 33.0, 60.0])) == 3


@pytest.mark.parametrize(
    ("speeds", "needle"),
    [
        ((25.0, 33.0, 42.0, 60.0), "too few distinct speeds: 4"),
        ((40.0, 45.0, 50.0, 55.0, 60.0), "speeds span only 40.0-60.0 m/s (ratio 1.50)"),
    ],
)
def test_refuses_a_design_that_cannot_separate_a_from_b(speeds: tuple[float, ...], needle: str) -> None:
    with pytest.raises(BallFitRefused, match=needle.replace("(", r"\(").replace(")", r"\)")):
        fit_ball([CcorPoint(v, 0.5 - 0.001 * v) for v in speeds])


def test_refuses_when_no_variant_is_identified() -> None:
    rising = [CcorPoint(v, 0.40 + 0.002 * v) for v in SPEEDS]  # no ball's CCOR rises with speed
    with pytest.raises(BallFitRefused, match="no variant is identified; a\\+b: a = 1 at its bound"):
        fit_ball(rising)


def test_refuses_u_for_some_points_only() -> None:
    pts = ccor_points(seed=2)
    pts[3] = CcorPoint(pts[3].speed_m_s, pts[3].ccor, 0.001, pts[3].ball_id)
    with pytest.raises(BallFitRefused, match="u_ccor is given for some points but not all"):
        fit_ball(pts)


def test_many_balls_are_left_out_in_folds_and_too_many_points_refused() -> None:
    pts = ccor_points(seed=5, balls=30)  # 150 balls
    data = fit_data(pts)
    assert data.n_balls == 150 and len(data.group_names) == 50 and set(data.groups) == set(range(50))
    with pytest.raises(BallFitRefused, match="too many points: 2005; a CCOR fit takes at most 2000"):
        fit_data(ccor_points(seed=5, balls=401))
