"""The efficiency curve eta(f) = COR(f)/COR_rigid (paper, Fig. 4): grid values, the optimum, anchors."""

from __future__ import annotations

import numpy as np
import pytest

from rig.physics import curve, fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams
from rig.physics.reference import solve_reference


@pytest.fixture(scope="module")
def curve_60(paper_params: CollisionParams) -> curve.EfficiencyCurve:
    """The paper's curve at 60.8 m/s, 300-5000 Hz on 40 points."""
    return curve.efficiency_curve(paper_params, 60.8, 300.0, 5000.0, 40)


# --- published anchors ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("speed", "hoop", "eta", "cor"),
    [(60.8, 1276.0, 1.391, 0.673), (26.8, 1124.0, 1.314, 0.682)],
)
def test_optimum_matches_published_anchor(
    paper_params: CollisionParams, speed: float, hoop: float, eta: float, cor: float
) -> None:
    """numerics.md 1.1: peaks at 1276 Hz (eta 1.391) and 1124 Hz (eta 1.314)."""
    res = curve.efficiency_curve(paper_params, speed, 300.0, 5000.0, 60)
    assert res.optimum_interior
    assert res.optimum_hz == pytest.approx(hoop, abs=1.0)
    assert res.optimum_efficiency == pytest.approx(eta, abs=1e-3)
    assert res.optimum_efficiency * res.cor_rigid == pytest.approx(cor, abs=1e-3)


def test_optimum_at_60_8_is_the_papers_1250_hz(curve_60: curve.EfficiencyCurve) -> None:
    """Paper, section 3 (Fig. 4): optimal hoop frequency approximately 1250 Hz."""
    assert curve_60.optimum_hz == pytest.approx(1250.0, rel=0.03)


def test_lower_speed_moves_the_peak_down(paper_params: CollisionParams) -> None:
    """Longer contact at lower speed: the optimum falls (numerics.md 1.1)."""
    peaks = [
        curve.efficiency_curve(paper_params, v, 300.0, 5000.0, 30).optimum_hz for v in (10.0, 26.8, 60.8)
    ]
    assert peaks[0] < peaks[1] < peaks[2]


# --- grid values ---------------------------------------------------------------------------------


@pytest.mark.parametrize("index", [0, 7, 13, 26, 39])
def test_grid_matches_independent_reference_solves(
    paper_params: CollisionParams, curve_60: curve.EfficiencyCurve, index: int
) -> None:
    """Grid eta, COR and contact time against scipy DOP853 at rtol 1e-12."""
    hoop = float(curve_60.hoop_hz[index])
    ref = solve_reference(Impact(paper_params, 60.8, hoop), "DOP853", 1e-12)
    ref_rigid = solve_reference(Impact(paper_params, 60.8), "DOP853", 1e-12)
    assert curve_60.cor[index] == pytest.approx(ref.cor, abs=1e-8)
    assert curve_60.contact_time_s[index] == pytest.approx(ref.contact_time_s, rel=1e-7)
    assert curve_60.cor_rigid == pytest.approx(ref_rigid.cor, abs=1e-10)
    assert curve_60.efficiency[index] == pytest.approx(ref.cor / ref_rigid.cor, abs=2e-8)


def test_grid_is_evenly_spaced_and_consistent(curve_60: curve.EfficiencyCurve) -> None:
    """Even grid from hoop_min to hoop_max; eta = COR / COR_rigid lane by lane."""
    np.testing.assert_allclose(curve_60.hoop_hz, np.linspace(300.0, 5000.0, 40), rtol=0, atol=1e-9)
    np.testing.assert_allclose(curve_60.efficiency, curve_60.cor / curve_60.cor_rigid, rtol=1e-15)
    assert np.all(curve_60.contact_time_s > 0.0)
    assert curve_60.rtol == fast.DEFAULT_RTOL


def test_cor_grid_matches_single_and_batch_solves(paper_params: CollisionParams) -> None:
    """The parallel lanes give the single-solve answers (same kernel, same steps): DOP853 throughout
    as fast.solve and solve_batch, and with the series steps as fast.solve_series (the default)."""
    hoops = np.array([150.0, 800.0, 1250.0, 4000.0, 2e4, 3e5])
    cor, tc = curve.cor_grid(paper_params, 26.8, hoops, series=0)
    impacts = [Impact(paper_params, 26.8, float(f)) for f in hoops]
    single = [fast.solve(imp) for imp in impacts]
    np.testing.assert_allclose(cor, [r.cor for r in single], rtol=0, atol=1e-14)
    np.testing.assert_allclose(tc, [r.contact_time_s for r in single], rtol=1e-14)
    batch_cor, batch_tc = fast.solve_batch(impacts)
    np.testing.assert_allclose(batch_cor, cor, rtol=0, atol=1e-14)
    np.testing.assert_allclose(batch_tc, tc, rtol=1e-14)
    series_cor, series_tc = curve.cor_grid(paper_params, 26.8, hoops)
    by_series = [fast.solve_series(imp) for imp in impacts]
    np.testing.assert_allclose(series_cor, [r.cor for r in by_series], rtol=0, atol=1e-14)
    np.testing.assert_allclose(series_tc, [r.contact_time_s for r in by_series], rtol=1e-14)
    np.testing.assert_allclose(series_cor, cor, rtol=0, atol=1e-9)  # both to fast.DEFAULT_RTOL


def test_cor_grid_counts_each_points_evaluations(paper_params: CollisionParams) -> None:
    """`evaluations` (the benchmark's floor) holds each point's right-hand side evaluations, those of
    later contacts too (150 Hz: the ball meets the barrel again), as a single solve counts them."""
    hoops = np.array([150.0, 1250.0, 2e4])
    counts = np.zeros(hoops.size, dtype=np.int64)
    contacts = np.zeros(hoops.size, dtype=np.int64)
    curve.cor_grid(paper_params, 60.8, hoops, contacts=contacts, evaluations=counts, series=0)
    single = [fast.solve(Impact(paper_params, 60.8, float(f))) for f in hoops]
    assert contacts[0] > 1
    assert counts.tolist() == [r.nfev for r in single]
    assert counts[2] > counts[1] > 12  # a stiffer barrel takes more steps, each 12 evaluations


def test_batch_lanes_with_mixed_models(paper_params: CollisionParams) -> None:
    """Rigid, flexible and pivoted impacts (2, 4 and 6 states) in one batch match single solves."""
    impacts = [
        Impact(paper_params, 60.8),
        Impact(paper_params, 0.01, 1e5),
        Impact(paper_params, 26.8, 1250.0, body_mass=0.6),
        Impact(paper_params, 5.0, None, body_mass=0.3),
        Impact(CollisionParams.build(c1=0.0, a=1.0, b=0.0), 1.0, 300.0),
    ]
    cor, tc = fast.solve_batch(impacts)
    for k, imp in enumerate(impacts):
        single = fast.solve(imp)
        assert cor[k] == pytest.approx(single.cor, abs=1e-14)
        assert tc[k] == pytest.approx(single.contact_time_s, rel=1e-14)
        assert cor[k] == pytest.approx(solve_reference(imp, "DOP853", 1e-10).cor, abs=1e-8)


def test_curve_is_unimodal_over_the_papers_band(curve_60: curve.EfficiencyCurve) -> None:
    """Fig. 4: eta rises to the optimum and falls after it; above 1 at the peak, below it at 300 Hz."""
    eta = curve_60.efficiency
    i = int(np.argmax(eta))
    assert np.all(np.diff(eta[: i + 1]) > 0.0)
    assert np.all(np.diff(eta[i:]) < 0.0)
    assert eta[0] < 1.0 < eta[i]


# --- optimum -------------------------------------------------------------------------------------


def test_optimum_is_refined_between_grid_points(
    paper_params: CollisionParams, curve_60: curve.EfficiencyCurve
) -> None:
    """The refined optimum lies between the best grid point's neighbours and beats every grid value."""
    i = int(np.argmax(curve_60.efficiency))
    assert curve_60.hoop_hz[i - 1] < curve_60.optimum_hz < curve_60.hoop_hz[i + 1]
    assert np.min(np.abs(curve_60.hoop_hz - curve_60.optimum_hz)) > 1.0  # not a grid point
    assert curve_60.optimum_efficiency >= float(np.max(curve_60.efficiency))
    # a local maximum of an independent evaluation
    eta = [curve.efficiency(paper_params, 60.8, curve_60.optimum_hz + df) for df in (-2.0, 0.0, 2.0)]
    assert eta[1] == pytest.approx(curve_60.optimum_efficiency, abs=1e-12)
    assert eta[0] < eta[1] > eta[2]


def test_optimum_is_stable_as_the_grid_changes(paper_params: CollisionParams) -> None:
    """12 to 57 grid points: the same optimum to 0.05 Hz and the same peak eta to 1e-9."""
    curves = [curve.efficiency_curve(paper_params, 60.8, 300.0, 5000.0, n) for n in (12, 23, 40, 57)]
    hz = np.array([c.optimum_hz for c in curves])
    eta = np.array([c.optimum_efficiency for c in curves])
    assert all(c.optimum_interior for c in curves)
    assert np.ptp(hz) < 0.05
    assert np.ptp(eta) < 1e-9


def test_unrefined_optimum_is_the_best_grid_point(paper_params: CollisionParams) -> None:
    """refine=False reports the grid's best point and its eta."""
    res = curve.efficiency_curve(paper_params, 60.8, 300.0, 5000.0, 20, refine=False)
    i = int(np.argmax(res.efficiency))
    assert res.optimum_hz == res.hoop_hz[i]
    assert res.optimum_efficiency == res.efficiency[i]
    assert res.optimum_interior


@pytest.mark.parametrize(("lo", "hi", "edge"), [(2000.0, 5000.0, 0), (300.0, 1000.0, -1)])
def test_optimum_at_an_edge_is_flagged(
    paper_params: CollisionParams, lo: float, hi: float, edge: int
) -> None:
    """Best value at an end of the grid: optimum_interior False, the end reported, no refinement."""
    res = curve.efficiency_curve(paper_params, 60.8, lo, hi, 15)
    assert not res.optimum_interior
    assert res.optimum_hz == res.hoop_hz[edge]
    assert res.optimum_efficiency == res.efficiency[edge]
    assert res.optimum_efficiency == float(np.max(res.efficiency))


def test_two_point_curve(paper_params: CollisionParams) -> None:
    """The smallest grid: two points, the optimum necessarily at an edge."""
    res = curve.efficiency_curve(paper_params, 60.8, 1000.0, 1500.0, 2)
    assert res.hoop_hz.size == 2
    assert not res.optimum_interior


def test_efficiency_and_rigid_cor_helpers(paper_params: CollisionParams) -> None:
    """efficiency() = COR(f)/rigid_cor(), both at the refinement tolerance."""
    e = curve.efficiency(paper_params, 26.8, 1124.0)
    cor = fast.solve(Impact(paper_params, 26.8, 1124.0), 1e-12).cor
    assert e == pytest.approx(cor / curve.rigid_cor(paper_params, 26.8), rel=1e-14)
    assert curve.rigid_cor(paper_params, 26.8) == pytest.approx(0.519, abs=1e-3)
