"""The check standard's control charts (rig.quality.charts) against hand calculations, a Monte Carlo
of the EWMA's run length, and properties over hard corners."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rig.core.errors import ParameterError
from rig.quality.charts import Session, b3_b4, build, c4, ewma_arl, ewma_run_length_quantile

# -- hand calculation --------------------------------------------------------------------------
# Phase I (M = 4), three hits a session: means 2, 3, 3, 2 (centre 2.5), moving ranges 1, 0, 1
# (mean 2/3), so sigma = (2/3) / (2/sqrt(pi)) = sqrt(pi)/3 and the action half-width is sqrt(pi).
# s = 1, 1, 2, 2; c4(3) = Gamma(3/2)/Gamma(1) = sqrt(pi)/2, so sigma_w = 1.5/c4 and the s centre
# for n = 3 is 1.5; B4(3) = 1 + 3 sqrt(1 - pi/4)/(sqrt(pi)/2).
HAND = [
    Session("r1", (1.0, 2.0, 3.0)),
    Session("r2", (2.0, 3.0, 4.0)),
    Session("r3", (1.0, 3.0, 5.0)),
    Session("r4", (0.0, 2.0, 4.0)),
    Session("r5", (4.0, 5.0, 6.0)),  # mean 5, s 1
    Session("r6", (2.0, 2.5, 3.0)),  # mean 2.5, s 0.5
    Session("r7", (0.0, 5.0, 10.0)),  # mean 5, s 5
]
SQRT_PI = math.sqrt(math.pi)


def test_individuals_and_s_limits_match_a_hand_calculation() -> None:
    charts = build(HAND, phase_i=4)
    limits = charts.limits()
    assert limits is not None
    assert charts.centre == pytest.approx(2.5)
    assert charts.sigma == pytest.approx(SQRT_PI / 3)
    assert limits["action_high"] == pytest.approx(2.5 + SQRT_PI)
    assert limits["action_low"] == pytest.approx(2.5 - SQRT_PI)
    assert limits["warning_high"] == pytest.approx(2.5 + 2 * SQRT_PI / 3)
    assert charts.sigma_within == pytest.approx(1.5 / (SQRT_PI / 2))
    b4 = 1 + 3 * math.sqrt(1 - math.pi / 4) / (SQRT_PI / 2)
    for p in charts.points:
        assert p.s_centre == pytest.approx(1.5)
        assert p.s_high == pytest.approx(b4 * 1.5)
        assert p.s_low == 0.0  # B3(3) = 0


def test_ewma_and_signals_match_a_hand_calculation() -> None:
    charts = build(HAND, phase_i=4)
    five, six, seven = charts.points[4:]
    # z_t = 0.2 x_t + 0.8 z_(t-1), z_0 = 2.5; half-width sqrt(pi) sqrt(1/9 (1 - 0.8^(2t)))
    assert five.ewma == pytest.approx(3.0)
    assert six.ewma == pytest.approx(2.9)
    assert seven.ewma == pytest.approx(3.32)
    for p, t in ((five, 1), (six, 2), (seven, 3)):
        half = SQRT_PI * math.sqrt((1 - 0.8 ** (2 * t)) / 9)
        assert p.ewma_high == pytest.approx(2.5 + half)
        assert p.ewma_low == pytest.approx(2.5 - half)
    got = {(s.rule, s.session) for s in charts.signals}
    assert got == {
        ("action limit", "r5"),
        ("EWMA", "r5"),  # 3.0 > 2.5 + 0.3545
        ("action limit", "r7"),
        ("EWMA", "r7"),  # 3.32 > 2.5 + 0.5075
        ("s-chart", "r7"),  # 5 > 3.852
    }
    line = next(s for s in charts.signals if s.rule == "s-chart").describe()
    assert "s-chart" in line and "session 7" in line and "r7" in line and "\n" not in line


def test_constants_match_the_tables() -> None:
    # ASTM/Montgomery tables: c4(5) 0.9400, B3(6) 0.030, B4(6) 1.970, B4(10) 1.716, B3(10) 0.284
    assert c4(5) == pytest.approx(0.9400, abs=5e-5)
    assert b3_b4(6) == pytest.approx((0.030, 1.970), abs=5e-4)
    assert b3_b4(10) == pytest.approx((0.284, 1.716), abs=5e-4)


# -- the EWMA's run length: the Markov chain against a Monte Carlo -----------------------------
def _monte_carlo_arl(shift: float, runs: int, seed: int) -> tuple[float, float]:
    """Mean and standard error of the run length of lambda 0.2, k 3 with asymptotic limits."""
    rng = np.random.default_rng(seed)
    h = 3.0 * math.sqrt(0.2 / 1.8)
    z = np.zeros(runs)
    length = np.zeros(runs, dtype=int)
    alive = np.ones(runs, dtype=bool)
    t = 0
    while alive.any():
        t += 1
        n = int(alive.sum())
        z[alive] = 0.2 * rng.normal(shift, 1.0, n) + 0.8 * z[alive]
        out = alive & (np.abs(z) > h)
        length[out] = t
        alive &= ~out
    return float(length.mean()), float(length.std(ddof=1) / math.sqrt(runs))


@pytest.mark.parametrize(("shift", "runs"), [(0.0, 3000), (1.0, 4000), (2.0, 4000)])
def test_ewma_arl_matches_a_monte_carlo(shift: float, runs: int) -> None:
    mc, se = _monte_carlo_arl(shift, runs, seed=24)
    assert ewma_arl(shift) == pytest.approx(mc, abs=4 * se)
    assert abs(ewma_arl(shift) - mc) / mc < 0.08  # and within 8 %


def test_run_length_quantile_brackets_the_arl() -> None:
    # a run length is at least 1, and its 99th percentile lies beyond its mean
    for shift in (0.5, 1.0, 3.0):
        assert 1 <= ewma_arl(shift) < ewma_run_length_quantile(shift, 0.99)
    assert ewma_arl(1.0) == pytest.approx(ewma_arl(-1.0))  # symmetric limits


# -- hard corners ------------------------------------------------------------------------------
finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False)
session_values = st.lists(finite, min_size=1, max_size=6)


@given(value=finite, n=st.integers(1, 6), sessions=st.integers(1, 30))
def test_constant_data_never_signals(value: float, n: int, sessions: int) -> None:
    charts = build(
        [Session(f"r{i}", (value,) * n) for i in range(sessions)], phase_i=min(20, max(2, sessions))
    )
    assert charts.signals == ()
    for p in charts.points:
        assert all(math.isfinite(x) for x in (p.mean, *(v for v in (p.ewma, p.s_high) if v is not None)))


@given(value=finite, other=finite)
def test_sigma_zero_signals_any_departure(value: float, other: float) -> None:
    sessions = [Session(f"r{i}", (value, value)) for i in range(3)] + [Session("x", (other, other))]
    charts = build(sessions, phase_i=3)
    assert charts.sigma == 0.0 and any("sigma 0" in n for n in charts.notes)
    rules = {s.rule for s in charts.signals}
    assert rules == (set() if other == value else {"action limit", "EWMA"})


@given(st.lists(session_values, min_size=0, max_size=1))
def test_one_session_builds_phase_i_only(values: list[list[float]]) -> None:
    charts = build([Session("r0", tuple(v)) for v in values])
    assert not charts.ready and charts.signals == () and charts.limits() is None
    assert "phase I" in charts.notes[0]


@given(
    st.lists(session_values, min_size=4, max_size=12),
    st.floats(min_value=-100, max_value=100),
    st.floats(min_value=0.5, max_value=4),
)
def test_signals_do_not_depend_on_the_units(values: list[list[float]], offset: float, scale: float) -> None:
    base = build([Session(f"r{i}", tuple(v)) for i, v in enumerate(values)], phase_i=3)
    assume(base.sigma and base.sigma > 1e-6)
    moved = build(
        [Session(f"r{i}", tuple(offset + scale * x for x in v)) for i, v in enumerate(values)], phase_i=3
    )

    def clear(c: object) -> set[str]:  # signals not on the edge of a limit (rounding may tip those)
        return {
            s.key
            for s in c.signals
            if abs(s.value - s.limit) > 1e-6 * (1 + abs(s.value))  # type: ignore[attr-defined]
        }

    assert clear(base) == clear(moved)
    assert all(s.index > 3 for s in base.signals)  # phase I points are shown, never judged


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_hit_is_refused_in_one_line(bad: float) -> None:
    with pytest.raises(ParameterError) as info:
        Session("run-7", (0.45, bad))
    assert "run-7" in str(info.value) and "finite" in str(info.value) and "\n" not in str(info.value)


def test_a_design_outside_its_range_is_refused() -> None:
    for kwargs in ({"phase_i": 1}, {"lam": 0.0}, {"k": -1.0}):
        with pytest.raises(ParameterError):
            build(HAND, **kwargs)  # type: ignore[arg-type]


def test_standard_values_judge_every_point_and_refuse_a_bad_sigma() -> None:
    sessions = [Session(f"r{i}", (x,)) for i, x in enumerate([0.5, -3.5, 0.0])]
    c = build(sessions, standard=(0.0, 1.0))
    assert c.given and c.phase_i == 0 and [p.phase for p in c.points] == [2, 2, 2]
    z1 = 0.2 * 0.5
    assert c.points[0].ewma == pytest.approx(z1) and c.points[1].ewma == pytest.approx(0.2 * -3.5 + 0.8 * z1)
    assert [(s.rule, s.index) for s in c.signals] == [("action limit", 2)]
    for bad in ((0.0, 0.0), (0.0, float("nan")), (float("inf"), 1.0)):
        with pytest.raises(ParameterError):
            build(sessions, standard=bad)
