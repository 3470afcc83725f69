"""The cross-check's power on one simulated population, and the simulated truth it rests on.

The simulated truth (studies.population.lab.true_metric, the simulated rig's own collision) is
checked against a separate solve of the collision model with the lab scene's true barrel written
here from rig.physics; the power check runs the calibration and cross-check as a lab would.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.core.units import INCH
from rig.physics import PivotedBat, predict_bat
from rig.population.calfile import CalibrationFile, calibration_record
from rig.population.calibrate import calibrate
from rig.population.crosscheck import crosscheck_bats
from rig.simulators.effects.trampoline import TrampolineConfig, bat_offset_bbcor
from rig.simulators.scene import Scene
from studies.population.lab import (
    SCAN_IN,
    best_scan_location,
    measured_population,
    scan_maximum,
    true_metric,
)
from studies.population.simulated import simulated_bat, simulated_population

LAB = Scene.load("lab")
TRAMP = next(e for e in LAB.effects if isinstance(e, TrampolineConfig))


def independent_bbcor(
    bat_id: str, hoop: float, moi: float, length_in: float, loc: float, extra: float
) -> float:
    """Rigid and flexible barrel with the scene's m2, c2, k1 scale, blended by the location weight,
    less the bending loss off the sweet spot."""
    assert TRAMP.m2 is not None and TRAMP.c2 is not None
    ball = LAB.ball
    params = ball.model_copy(update={"m2": TRAMP.m2, "c2": TRAMP.c2, "k1": ball.k1 * TRAMP.k1_scale})
    q = (length_in - loc) * INCH - LAB.rig.pivot_from_knob_m
    pivoted = PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)
    e_r = predict_bat(params, 60.8, None, pivoted).e_a
    e_h = predict_bat(params, 60.8, hoop, pivoted).e_a
    k = ball.m1 * q * q / moi  # BBCOR = e_A (1 + k) + k
    e_h += (bat_offset_bbcor(LAB.seed, bat_id, TRAMP.spread_bbcor) + extra) / (1 + k)
    q_s = length_in * INCH - TRAMP.sweet_spot_from_tip_m - LAB.rig.pivot_from_knob_m
    w = math.exp(-0.5 * ((q - q_s) / TRAMP.width_m) ** 2)
    loss = TRAMP.off_node_loss_bbcor * (1 - w) / (1 + k)  # bending loss off the sweet spot
    return (e_r + w * (e_h - e_r) - loss) * (1 + k) + k


@pytest.mark.parametrize("index", [1, 7, 23])
@pytest.mark.parametrize("alteration", [0.0, 0.025])
@pytest.mark.parametrize("loc", [6.5, 5.5])
def test_truth_is_the_scene_model(index: int, alteration: float, loc: float) -> None:
    bat = simulated_bat(3, index, alteration)
    s = bat.spec
    assert s.hoop_hz is not None
    expected = independent_bbcor(s.id, s.hoop_hz, bat.moi_kgm2, s.length_in, loc, alteration)
    assert true_metric(LAB, bat, loc) == pytest.approx(expected, abs=1e-9)


def test_alteration_raises_the_truth_by_its_amount_at_the_sweet_spot() -> None:
    legal, altered = simulated_bat(5, 4), simulated_bat(5, 4, 0.025)
    # the ids differ (ALT- prefix), so the bats' own offsets differ: take them out
    off = bat_offset_bbcor(LAB.seed, altered.spec.id, TRAMP.spread_bbcor) - bat_offset_bbcor(
        LAB.seed, legal.spec.id, TRAMP.spread_bbcor
    )
    sweet = TRAMP.sweet_spot_from_tip_m / INCH  # w = 1 there
    diff = true_metric(LAB, altered, sweet) - true_metric(LAB, legal, sweet)
    assert diff == pytest.approx(0.025 + off, abs=1e-9)


def test_scan_maximum_is_the_grid_argmax() -> None:
    bat = simulated_bat(2, 9)
    values = {loc: true_metric(LAB, bat, loc) for loc in SCAN_IN}
    best = scan_maximum(LAB, bat)
    assert all(values[best] >= v for v in values.values())


def test_power_on_one_population_meets_the_goal() -> None:
    """40 legal bats calibrate; 40 fresh legal bats and their +0.025 twins are cross-checked.

    Noise and recorded u as benchmarks/bench_crosscheck.py measures them on simulated certified
    runs (sd of certified - truth 0.0003, median recorded u 0.0009), here rounded up.
    """
    rng = np.random.default_rng(11)
    noise, u = 0.0005, 0.001
    train = measured_population(LAB, simulated_population(40, 11), best_scan_location, noise, rng, u=u)
    cal = calibrate(train, "bbcor")
    record = CalibrationFile.model_validate(calibration_record(cal, b"sim", "sim"))
    fresh = measured_population(LAB, simulated_population(40, 100_011), best_scan_location, noise, rng, u=u)
    legal = crosscheck_bats(record, fresh)
    altered = crosscheck_bats(record, [b.model_copy(update={"bbcor": (b.bbcor or 0) + 0.025}) for b in fresh])
    false_flags = sum(bool(c.flagged) for c in legal)
    detected = sum(bool(c.flagged) for c in altered)
    rmse = math.sqrt(sum((c.measured - c.predicted) ** 2 for c in legal if c.measured) / len(legal))
    assert false_flags <= 4, [c.z for c in legal]
    assert detected >= 30, [c.z for c in altered]
    assert rmse <= 0.007
    # the interval is not trivially wide: a legal bat's half-width stays below the alteration
    assert max(c.interval[1] - c.predicted for c in legal) < 0.025


def test_gradient_step_stays_below_the_bats_own_mass() -> None:
    """A loosely identified m2 close to a bat's I/Q^2: the delta method's step must not cross it.

    Before, the step up (0.05 sigma) put m2 above the bat's effective mass and the solve raised.
    """
    rng = np.random.default_rng(3)
    train = measured_population(LAB, simulated_population(12, 3), best_scan_location, 0.0005, rng, u=0.001)
    cal = calibrate(train, "bbcor", variants=("m2+c2+k1_scale",))
    record = calibration_record(cal, b"sim", "sim")
    bat = train[0].model_copy(update={"bat_id": "HEAVY-M2"})
    assert bat.moi_kgm2 is not None and bat.length_in is not None and bat.location_in is not None
    q = (bat.length_in - bat.location_in) * INCH - LAB.rig.pivot_from_knob_m
    eff = bat.moi_kgm2 / q**2
    record["parameters"] = {**record["parameters"], "m2": 0.98 * eff}
    record["model_params"] = {**record["model_params"], "m2": 0.98 * eff}
    cov = np.array(record["covariance"])
    cov[0, 0] = (0.5 * eff) ** 2  # sigma of m2 half the bat's mass: a step of 0.05 sigma crosses it
    cov[0, 1:] = cov[1:, 0] = 0.0
    record["covariance"] = cov.tolist()
    record["uncertainty"] = {**record["uncertainty"], "m2": 0.5 * eff}  # the root of its variance
    (check,) = crosscheck_bats(CalibrationFile.model_validate(record), [bat])
    assert math.isfinite(check.u_model) and check.u_model > 0.0


@pytest.mark.parametrize("index", range(1, 9))
def test_the_lab_scan_peaks_near_the_sweet_spot(index: int) -> None:
    """Across 1400-3000 Hz the true maximum lies at 6.0-7.5 in, inside the procedure's scan."""
    assert 6.0 <= scan_maximum(LAB, simulated_bat(6, index)) <= 7.5
