"""The pure-Python Student-t quantile against scipy.stats (an independent implementation)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import t as student_t

from rig.measure.student import cdf, pdf, quantile, two_sided


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 5, 6, 7, 10, 17, 38, 39, 100, 398, 3997, 20000])
@pytest.mark.parametrize("p", [0.6, 0.75, 0.9, 0.95, 0.975, 0.995, 0.9995, 0.99995, 0.025, 0.3])
def test_quantile_matches_scipy(dof: int, p: float) -> None:
    assert quantile(p, dof) == pytest.approx(float(student_t.ppf(p, dof)), rel=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 6000), st.floats(0.5005, 0.99995))
def test_quantile_matches_scipy_anywhere(dof: int, p: float) -> None:
    assert quantile(p, dof) == pytest.approx(float(student_t.ppf(p, dof)), rel=1e-8)


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 3000), st.floats(-50.0, 50.0))
def test_cdf_and_pdf_match_scipy(dof: int, t: float) -> None:
    assert cdf(t, dof) == pytest.approx(float(student_t.cdf(t, dof)), rel=1e-10, abs=1e-13)
    assert pdf(t, dof) == pytest.approx(float(student_t.pdf(t, dof)), rel=1e-10, abs=1e-300)


def test_known_values_and_limits() -> None:
    """The textbook table: t(0.975, 38) = 2.0244; nu = 1 is Cauchy; a large nu tends to the normal."""
    assert quantile(0.975, 38) == pytest.approx(2.02439, abs=1e-5)
    assert quantile(0.75, 1) == pytest.approx(1.0, rel=1e-12)  # tan(pi / 4)
    assert quantile(0.975, 10**6) == pytest.approx(1.959966, abs=1e-5)
    assert quantile(0.5, 7) == 0.0
    assert quantile(0.1, 7) == -quantile(0.9, 7)
    assert two_sided(math.inf, 5) == 1.0


@pytest.mark.parametrize("bad", [(0.0, 5), (1.0, 5), (0.9, 0), (0.9, 2.5), (math.nan, 5)])
def test_refuses_what_has_no_quantile(bad: tuple[float, int]) -> None:
    with pytest.raises(ValueError):
        quantile(*bad)  # type: ignore[arg-type]
