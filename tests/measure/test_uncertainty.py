"""GUM propagation with correlations: Jacobian, Monte Carlo agreement, cancellation, systematic floor."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core.errors import ParameterError
from rig.measure.model import outputs
from rig.measure.speeds import ShotDataError, shot_speeds, split_passes
from rig.measure.uncertainty import (
    OUTPUTS,
    ShotInputs,
    Spread,
    UncertaintyModel,
    budget,
    jacobian,
    monte_carlo,
    u_with_scatter,
)
from tests.measure.shots import BALL, CFG, MOI, POS, Q, shot_ticks, typical_shot

QUANT_ONLY = UncertaintyModel(trigger_jitter=Spread(width=0.0))  # timing from tick quantization alone


def test_jacobian_matches_analytic_partials_and_central_differences() -> None:
    shot = typical_shot()
    J = jacobian(shot)
    p = shot.vector()
    dt_in = p[1] - p[0]
    v_in, _v_out, e, _bb, _ = outputs(p, shot.gates)
    k = BALL * Q**2 / MOI
    i = OUTPUTS.index
    assert J[i("v_in"), 1] == pytest.approx(-v_in / dt_in, rel=1e-12)  # d v_in / d t_in_b
    assert J[i("v_in"), 5] == pytest.approx(1.0 / dt_in, rel=1e-12)  # d v_in / d x2
    assert J[i("e_a"), 5] == 0.0 and J[i("e_a"), 6] == 0.0  # spacing cancels in e_A, exactly
    assert J[i("bbcor"), 11] == pytest.approx(-(1 + e) * k / MOI, rel=1e-12)
    assert J[i("bbcor"), 10] == pytest.approx((1 + e) * 2 * k / Q, rel=1e-12)
    for j in range(p.size):
        h = 1e-6 * max(abs(p[j]), 1e-3)
        up, dn = p.copy(), p.copy()
        up[j] += h
        dn[j] -= h
        fd = (outputs(up, shot.gates) - outputs(dn, shot.gates)) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-5, atol=1e-9 * np.abs(J).max())


def test_contributions_add_up_and_moi_dominates_bbcor() -> None:
    b = budget(typical_shot())
    np.testing.assert_allclose(b.contributions.sum(axis=1), b.u**2, rtol=1e-12)
    assert b.ranked("bbcor")[0][0] == "I"
    assert b.ranked("bbcor")[0][1] > 0.5
    assert b.expanded("bbcor") == pytest.approx(2 * b.u_of("bbcor"))
    assert b.value("bbcor") == pytest.approx(0.4635, abs=1e-4)


@pytest.mark.parametrize("v_out", [11.0, 3.0])
def test_linear_budget_agrees_with_monte_carlo(v_out: float) -> None:
    shot = typical_shot(v_out=v_out)
    lin, mc = budget(shot), monte_carlo(shot, draws=200_000, rng=1)
    np.testing.assert_allclose(mc.u, lin.u, rtol=0.03)
    np.testing.assert_allclose(mc.correlation, lin.correlation, atol=0.02)
    np.testing.assert_allclose(mc.mean, lin.values, rtol=1e-4)


def test_mean_of_six_agrees_with_monte_carlo() -> None:
    hits = [typical_shot(v_in=v) for v in (60.6, 60.7, 60.8, 60.8, 60.9, 61.0)]
    lin, mc = budget(hits), monte_carlo(hits, draws=60_000, rng=np.random.default_rng(7))
    np.testing.assert_allclose(mc.u, lin.u, rtol=0.03)


def _naive_u_e(b) -> float:
    """u(e_A) if v_in and v_out were propagated as independent values."""
    i = OUTPUTS.index
    rel = math.hypot(b.u[i("v_in")] / b.values[i("v_in")], b.u[i("v_out")] / b.values[i("v_out")])
    return b.values[i("e_a")] * rel


def test_gate_spacing_cancels_in_e_a() -> None:
    b = budget(typical_shot(), QUANT_ONLY)
    assert b.u_of("e_a") < _naive_u_e(b) / 10
    # default jitter: timing matters too, but the correlated result is still well below the naive one
    d = budget(typical_shot())
    assert d.u_of("e_a") < 0.6 * _naive_u_e(d)
    assert d.correlation[OUTPUTS.index("v_in"), OUTPUTS.index("v_out")] > 0.5


def test_position_tolerance_does_not_reach_e_a_when_the_same_pair_times_both_passes() -> None:
    loose = QUANT_ONLY.model_copy(update={"gate_position": Spread(width=0.005, shape="rectangular")})
    tight, wide = budget(typical_shot(), QUANT_ONLY), budget(typical_shot(), loose)
    assert wide.u_of("v_in") > 20 * tight.u_of("v_in")
    assert wide.u_of("e_a") == pytest.approx(tight.u_of("e_a"), rel=1e-9)
    # ...but it does when the passes use different pairs (rebound over 3 -> 1, gate 2 missed)
    span = ShotInputs.ideal(60.8, 11.0, POS, CFG.tick_s, Q, MOI, BALL, gates=(2, 3, 3, 1))
    assert budget(span, loose).u_of("e_a") > 10 * budget(span, QUANT_ONLY).u_of("e_a")


def test_systematic_floor_per_bat() -> None:
    one = budget(typical_shot())
    rand, sys = one.random_variance("bbcor"), one.systematic_variance("bbcor")
    for n in (2, 6, 20):
        mean = budget([typical_shot()] * n)
        assert mean.u_of("bbcor") ** 2 == pytest.approx(rand / n + sys, rel=1e-9)
        assert mean.u_of("bbcor") >= math.sqrt(sys)
    six = budget([typical_shot()] * 6)
    assert six.u_of("bbcor") > 0.99 * one.u_of("bbcor")  # not the 1/sqrt(6) = 0.41 a naive mean claims
    # e_A has no shared input here (spacing cancels), so it does average down as 1/sqrt(n)
    assert six.u_of("e_a") == pytest.approx(one.u_of("e_a") / math.sqrt(6), rel=1e-9)


def test_budget_from_real_ticks_matches_the_ideal_shot() -> None:
    ticks = shot_ticks(60.8, 11.0, start=(1 << 32) - 40_000)  # counter wraps mid-shot
    passes = split_passes(ticks, CFG)
    real = ShotInputs.from_passes(passes, POS, CFG, Q, MOI, BALL)
    sp = shot_speeds(passes, POS, CFG)
    b = budget(real)
    assert b.value("v_in") == pytest.approx(sp.inbound, rel=1e-12)
    assert b.value("v_out") == pytest.approx(sp.rebound, rel=1e-12)
    np.testing.assert_allclose(b.u, budget(typical_shot()).u, rtol=1e-3)


def test_hits_must_share_the_systematic_inputs() -> None:
    other = ShotInputs.ideal(60.8, 11.0, POS, CFG.tick_s, Q, MOI * 1.01, BALL)
    with pytest.raises(ParameterError, match="same for every hit"):
        budget([typical_shot(), other])
    with pytest.raises(ParameterError):
        budget([])


def test_equal_or_reversed_times_are_refused() -> None:
    with pytest.raises(ShotDataError, match="no speed"):
        ShotInputs((0.0, 0.0, 0.01, 0.02), (2, 3, 3, 2), POS, Q, MOI, BALL, CFG.tick_s)
    with pytest.raises(ShotDataError, match="no gate pair"):
        ShotInputs.from_passes(split_passes(shot_ticks(60.8, 11.0)[:4], CFG), POS, CFG, Q, MOI, BALL)


@given(v_in=st.floats(0.05, 300.0), v_out=st.floats(0.01, 300.0))
def test_budget_stays_finite_over_extreme_speeds(v_in: float, v_out: float) -> None:
    b = budget(typical_shot(v_in, v_out))
    assert np.all(np.isfinite(b.covariance)) and np.all(np.isfinite(b.values))
    assert np.all(np.isfinite(b.correlation))


@given(
    v_in=st.floats(5.0, 150.0),
    v_out=st.floats(0.5, 100.0),
    start=st.integers(0, (1 << 32) - 1),
)
def test_budget_from_ticks_with_wrap_anywhere(v_in: float, v_out: float, start: int) -> None:
    passes = split_passes(shot_ticks(v_in, v_out, start=start), CFG)
    try:
        shot = ShotInputs.from_passes(passes, POS, CFG, Q, MOI, BALL)
    except ShotDataError:
        return  # e.g. a pair quantized to equal ticks: the typed refusal is the right answer
    ref = ShotInputs.from_passes(
        split_passes(shot_ticks(v_in, v_out, start=1000), CFG), POS, CFG, Q, MOI, BALL
    )
    assert shot.times_s == ref.times_s
    assert np.all(np.isfinite(budget(shot).u))


def test_observed_scatter_enters_above_the_modelled_random_part() -> None:
    six = budget([typical_shot()] * 6)
    sys = six.systematic_variance("bbcor")
    spread = [0.460, 0.465, 0.462, 0.468, 0.458, 0.463]
    s2 = float(np.var(spread, ddof=1)) / 6
    assert u_with_scatter(six, spread) == pytest.approx(math.sqrt(s2 + sys), rel=1e-12)
    tiny = [0.4635 + 1e-7 * i for i in range(6)]  # less scatter than timing noise alone allows
    assert u_with_scatter(six, tiny) == pytest.approx(six.u_of("bbcor"), rel=1e-12)
    with pytest.raises(ParameterError):
        u_with_scatter(six, spread[:5])
