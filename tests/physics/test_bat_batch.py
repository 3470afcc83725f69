"""The array-built lanes of many pivoted bats give solve_batch's numbers over impact_for's Impacts."""

from __future__ import annotations

import numpy as np
import pytest

from rig.core.errors import ParameterError
from rig.physics import DEFAULT_PARAMS, PivotedBat, predict_bat, solve_batch
from rig.physics.bat import impact_for
from rig.physics.bat_batch import pivoted_cor_batch, pivoted_cor_sets


@pytest.mark.parametrize(
    "update", [{}, {"m2": 0.24, "c2": 300.0, "k1": 0.9 * DEFAULT_PARAMS.k1}, {"c2": 0.0}]
)
def test_equals_solve_batch_over_impacts(update: dict[str, float]) -> None:
    params = DEFAULT_PARAMS.model_copy(update={"m1": 0.145, **update})
    rng = np.random.default_rng(1)
    hoops = rng.uniform(1200.0, 3500.0, 50)
    bats = [
        PivotedBat(moi_kgm2=float(m), impact_from_pivot_m=float(q))
        for m, q in zip(rng.uniform(0.15, 0.23, 50), rng.uniform(0.5, 0.6, 50), strict=True)
    ]
    cor, tc = pivoted_cor_batch(params, 60.8, hoops, np.array([b.effective_mass for b in bats]), rtol=1e-9)
    ref_cor, ref_tc = solve_batch(
        [impact_for(params, 60.8, float(h), b) for h, b in zip(hoops, bats, strict=True)], rtol=1e-9
    )
    np.testing.assert_array_equal(cor, ref_cor)
    np.testing.assert_array_equal(tc, ref_tc)
    assert cor[0] == pytest.approx(
        predict_bat(params, 60.8, float(hoops[0]), bats[0], rtol=1e-9).e_a, rel=1e-12
    )


def test_refuses_a_bat_lighter_than_its_barrel() -> None:
    params = DEFAULT_PARAMS.model_copy(update={"m2": 0.5})
    with pytest.raises(ParameterError, match="must exceed the barrel mass"):
        pivoted_cor_batch(params, 60.8, np.array([2000.0, 2000.0]), np.array([1.0, 0.4]))


def test_several_sets_in_one_batch_give_each_sets_own_numbers() -> None:
    sets = [
        DEFAULT_PARAMS.model_copy(update={"m2": m2, "c2": c2}) for m2, c2 in ((0.09, 200.0), (0.24, 300.0))
    ]
    hoops, eff = np.array([1400.0, 2200.0, 3000.0]), np.array([0.5, 0.9, 1.4])
    cor, tc = pivoted_cor_sets(sets, 60.8, hoops, eff, rtol=1e-9)
    assert cor.shape == tc.shape == (2, 3) and cor[0, 0] != cor[1, 0]
    for row, params in enumerate(sets):
        one_cor, one_tc = pivoted_cor_batch(params, 60.8, hoops, eff, rtol=1e-9)
        np.testing.assert_array_equal(cor[row], one_cor)
        np.testing.assert_array_equal(tc[row], one_tc)
    assert pivoted_cor_sets([], 60.8, hoops, eff)[0].shape == (0, 3)
