"""rig.quality.scores against hand calculations, a second Algorithm A written here, and Monte Carlo."""

from __future__ import annotations

import math
import random
import statistics

import numpy as np
import pytest

from rig.core.errors import ParameterError
from rig.quality.scores import MIN_ROBUST, algorithm_a, assess_en, assess_z, en_score, score, z_score


def reference_algorithm_a(values: list[float]) -> tuple[float, float]:
    """ISO 13528 Annex C Algorithm A written out plainly (lists, statistics), iterated until the
    third significant figure of s* and the matching figure of x* stop changing, then 50 times more."""
    x = statistics.median(values)
    s = 1.483 * statistics.median([abs(v - x) for v in values])
    for _ in range(200):
        d = 1.5 * s
        w = [x - d if v < x - d else x + d if v > x + d else v for v in values]
        x = sum(w) / len(w)
        s = 1.134 * math.sqrt(sum((v - x) ** 2 for v in w) / (len(w) - 1))
    return x, s


def test_en_by_hand() -> None:
    # x = 0.4638, U = 0.0084; X = 0.4537, U = 0.0109: E_n = 0.0101 / sqrt(0.0084^2 + 0.0109^2)
    #   = 0.0101 / sqrt(7.056e-5 + 1.1881e-4) = 0.0101 / 0.01376118 = 0.733949
    assert en_score(0.4638, 0.0084, 0.4537, 0.0109) == pytest.approx(0.733949, abs=2e-6)
    assert en_score(0.4537, 0.0109, 0.4638, 0.0084) == pytest.approx(-0.733949, abs=2e-6)
    assert en_score(10.0, 3.0, 6.0, 4.0) == pytest.approx(0.8)  # a 3-4-5 triangle


@pytest.mark.parametrize(
    ("en", "says"),
    [(0.0, "satisfactory"), (1.0, "satisfactory"), (-1.0, "satisfactory"), (1.0001, "unsatisfactory")],
)
def test_en_assessment(en: float, says: str) -> None:
    assert assess_en(en) == says


@pytest.mark.parametrize(
    ("z", "says"),
    [
        (2.0, "satisfactory"),
        (-2.0, "satisfactory"),
        (2.01, "questionable"),
        (-2.99, "questionable"),
        (3.0, "unsatisfactory"),
        (-3.5, "unsatisfactory"),
    ],
)
def test_z_assessment(z: float, says: str) -> None:
    assert assess_z(z) == says


def test_z_by_hand() -> None:
    assert z_score(42.5, 42.1, 0.16) == pytest.approx(2.5)  # 0.4 / 0.16
    s = score(42.5, 0.3, 42.1, 0.4, 0.16)
    assert (s.difference, s.en, s.en_assessment) == (pytest.approx(0.4), pytest.approx(0.8), "satisfactory")
    assert s.z_assessment == "questionable"
    assert score(42.5, 0.3, 42.1, 0.4, None).z is None


@pytest.mark.parametrize(
    ("call", "names"),
    [
        (lambda: en_score(1.0, 0.0, 1.0, 0.1), "U_x"),
        (lambda: en_score(1.0, 0.1, 1.0, -0.1), "U_X"),
        (lambda: en_score(math.nan, 0.1, 1.0, 0.1), "x"),
        (lambda: en_score(1.0, 0.1, math.inf, 0.1), "X"),
        (lambda: z_score(1.0, 1.0, 0.0), "sigma_pt"),
        (lambda: z_score(1.0, 1.0, math.nan), "sigma_pt"),
    ],
)
def test_refusals_name_the_value(call, names: str) -> None:
    with pytest.raises(ParameterError) as info:
        call()
    assert info.value.name == names and "\n" not in str(info.value)


@pytest.mark.parametrize("seed", range(6))
def test_algorithm_a_matches_a_second_implementation(seed: int) -> None:
    rng = random.Random(seed)
    values = [rng.gauss(0.0, 0.01) for _ in range(rng.randint(MIN_ROBUST, 40))]
    values += [rng.uniform(0.05, 0.2) for _ in range(rng.randint(0, 3))]  # outliers
    got = algorithm_a(values)
    x, s = reference_algorithm_a(values)
    assert got.mean == pytest.approx(x, rel=1e-9, abs=1e-15)
    assert got.sd == pytest.approx(s, rel=1e-9)
    assert got.p == len(values)


def test_algorithm_a_fixed_point_by_hand() -> None:
    # 1 1 1 1 2 2 2 100: at the fixed point only 100 is clipped (to x + 1.5 s), so
    # 8x = 10 + x + 1.5s, i.e. x = (10 + 1.5s) / 7, and s = 1.134 sqrt((4(1-x)^2 + 3(2-x)^2 + (1.5s)^2) / 7);
    # s solved by bisection on that one equation
    def gap(s: float) -> float:
        x = (10 + 1.5 * s) / 7
        return 1.134 * math.sqrt((4 * (1 - x) ** 2 + 3 * (2 - x) ** 2 + (1.5 * s) ** 2) / 7) - s

    low, high = 0.1, 2.0
    for _ in range(100):
        mid = (low + high) / 2
        low, high = (mid, high) if gap(mid) > 0 else (low, mid)
    s = (low + high) / 2
    got = algorithm_a([1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 1.0, 100.0])
    assert got.sd == pytest.approx(s, rel=1e-9)
    assert got.mean == pytest.approx((10 + 1.5 * s) / 7, rel=1e-9)
    assert got.mean + 1.5 * got.sd > 2.0  # the assumption: only 100 is clipped


def test_algorithm_a_estimates_a_normal_sd_despite_outliers() -> None:
    rng = np.random.default_rng(7)
    estimates = []
    for _ in range(300):
        data = rng.normal(0.0, 1.0, 40)
        data[:2] = 25.0  # 5 % gross errors
        estimates.append(algorithm_a(list(data)).sd)
    # the plain SD would be about 5.5; Algorithm A stays near 1 (slightly above: the errors widen it)
    assert 0.95 < float(np.mean(estimates)) < 1.25


def test_algorithm_a_refuses_too_few_and_no_spread() -> None:
    with pytest.raises(ParameterError, match=f"at least {MIN_ROBUST}"):
        algorithm_a([0.1] * (MIN_ROBUST - 1))
    with pytest.raises(ParameterError, match="spread is zero"):
        algorithm_a([0.1] * 5 + [0.2, 0.3, 0.4])
    with pytest.raises(ParameterError, match="finite"):
        algorithm_a([0.1, 0.2, math.nan] + [0.3] * 8)
