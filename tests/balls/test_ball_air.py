"""The lot's wear and air sensitivities: closed forms, a Monte Carlo of the stated u, the simulated lab."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.balls import run_ball_test
from rig.core.ball import BallLot, CcorPoint, Conditioning, LotResult
from rig.physics import rigid_cor
from rig.protocols.ball_air import fit_air, pooled_wear
from rig.protocols.ball_eval import within_ball_fit
from rig.protocols.ball_procedure import BallProcedure
from rig.protocols.ball_terms import BallTerms, HitBall, adjust, terms_from_lot
from rig.session import air_starting_at, sim_config
from rig.simulators.scene import Scene
from rig.store import Store

NOMINAL_V = 26.8


def point(ball: str, hit: int, speed: float, cor: float) -> CcorPoint:
    return CcorPoint(
        speed_m_s=speed, target_speed_m_s=NOMINAL_V, cor=cor, u=1e-4, ball_id=ball, ball_hit=hit, shot=0
    )


@settings(max_examples=60, deadline=None)
@given(
    wear=st.floats(-1e-3, 0.0),
    per_speed=st.floats(-5e-3, 0.0),
    levels=st.lists(st.floats(0.45, 0.58), min_size=2, max_size=8),
    seed=st.integers(0, 10_000),
)
def test_within_ball_fit_recovers_wear_and_speed_slope_exactly(
    wear: float, per_speed: float, levels: list[float], seed: int
) -> None:
    """Noise-free COR = level(ball) + wear * hit + per_speed * (v - 26.8): both slopes come back."""
    rng = random.Random(seed)
    pts = []
    for b, level in enumerate(levels):
        for hit in range(1, 5):
            v = NOMINAL_V + rng.gauss(0.0, 0.15)
            pts.append(point(f"B{b}", hit, v, level + wear * hit + per_speed * (v - NOMINAL_V)))
    fit = within_ball_fit(pts)
    assert fit.slope == pytest.approx(wear, abs=1e-9)
    assert fit.speed_slope == pytest.approx(per_speed, abs=1e-8)


def test_speed_scatter_no_longer_passes_for_wear() -> None:
    """With the speed drifting up within each ball, a hit-only slope is biased; the joint fit is not."""
    rng = random.Random(3)
    pts = []
    for b in range(6):
        for hit in range(1, 5):
            v = NOMINAL_V + 0.05 * hit + rng.gauss(0.0, 0.13)
            pts.append(point(f"B{b}", hit, v, 0.52 - 0.0003 * hit - 0.0016 * (v - NOMINAL_V)))
    naive = np.polyfit([p.ball_hit for p in pts], [p.cor for p in pts], 1)[0]
    assert naive < -0.00035  # the hit-only slope takes the speed's share
    assert within_ball_fit(pts).slope == pytest.approx(-0.0003, abs=1e-9)


def test_a_constant_speed_leaves_the_hit_count_alone() -> None:
    pts = [
        point(b, n, NOMINAL_V, base - 0.001 * n) for b, base in (("A", 0.52), ("B", 0.50)) for n in (1, 2, 3)
    ]
    fit = within_ball_fit(pts)
    assert fit.slope == pytest.approx(-0.001) and fit.speed_slope is None


def result(
    mean: float, temp: float, rh: float, sd: float = 0.001, n: int = 6, wear: float = -3e-4
) -> LotResult:
    """A ball-cor result with `n` balls scattered by `sd` about `mean` (exactly: +-sd alternately)."""
    per_ball = {f"B{i}": mean + sd * (1 if i % 2 else -1) * math.sqrt((n - 1) / n) for i in range(n)}
    return LotResult(
        lot_id="L",
        procedure="ball-cor",
        quantity="cor",
        target={"kind": "plate"},
        speeds_m_s=(NOMINAL_V,),
        mean=mean,
        u=0.001,
        U=0.002,
        coverage_k=2.0,
        sd_between_balls=sd,
        wear_per_hit=wear,
        wear_per_hit_u=1e-5,
        mean_hit=2.5,
        n_balls=n,
        hits_per_ball=4,
        n_hits=4 * n,
        temp_c=temp,
        rh_pct=rh,
        run_id="r",
        per_ball=per_ball,
    )


def test_air_fit_recovers_independent_sensitivities() -> None:
    """Temperature and humidity varied independently, no noise: both sensitivities come back."""
    s_t, s_rh = 0.0015, -0.0006
    grid = [(t, h) for t in (19.0, 21.0, 23.0) for h in (40.0, 50.0, 60.0)]
    results = [result(0.52 + s_t * (t - 21) + s_rh * (h - 50), t, h, sd=1e-7) for t, h in grid]
    fit = fit_air(results, 21.0, 50.0, 0.002, 0.001)
    assert fit is not None
    assert fit.cor_per_c == pytest.approx(s_t, rel=1e-3)
    assert fit.cor_per_pct_rh == pytest.approx(s_rh, rel=1e-3)
    assert fit.cor_nominal == pytest.approx(0.52, abs=1e-7)


def test_air_fit_degrees_of_freedom_count_what_the_data_determine() -> None:
    """Independent T and RH: a vague prior leaves n - 3 degrees of freedom, a tight one n - 1."""
    grid = [(t, h) for t in (19.0, 21.0, 23.0) for h in (40.0, 50.0, 60.0)]
    results = [result(0.52 + 0.001 * (t - 21), t, h, sd=0.001) for t, h in grid]
    vague = fit_air(results, 21.0, 50.0, 10.0, 10.0)
    tight = fit_air(results, 21.0, 50.0, 1e-9, 1e-9)
    assert vague is not None and tight is not None
    assert vague.dof == pytest.approx(len(grid) - 3, abs=1e-6)
    assert tight.dof == pytest.approx(len(grid) - 1, abs=1e-3)


def test_air_fit_needs_three_results_spanning_the_air() -> None:
    assert fit_air([result(0.52, 21, 50), result(0.53, 23, 45)], 21.0, 50.0, 0.002, 0.001) is None
    flat = [result(0.52, 21.0 + 0.1 * i, 50.0 + 0.5 * i) for i in range(4)]
    assert fit_air(flat, 21.0, 50.0, 0.002, 0.001) is None


def test_air_fit_stated_u_is_honest_on_a_swinging_lab() -> None:
    """Monte Carlo: T and RH move together (a swing) with sensor noise; over many lots, the fitted
    correction for a bat test's air on the same swing is within 2 of its stated u about 95 % of the time."""
    s_t, s_rh, sd, n = 0.00146, -0.00059, 0.0011, 6
    rng = np.random.default_rng(20)
    inside, trials = 0, 400
    for _ in range(trials):
        results = []
        for k in range(4):
            swing = math.sin(2 * math.pi * k / 4 + rng.uniform(0, 0.3))
            t, h = 21 + 1.5 * swing + rng.normal(0, 0.05), 50 - 5 * swing + rng.normal(0, 0.3)
            balls = rng.normal(0.52, sd, n)  # a new draw of the lot's spread in each test
            res = result(0.52 + s_t * (t - 21) + s_rh * (h - 50), t, h, sd=sd, n=n)
            results.append(
                res.model_copy(
                    update={
                        "mean": float(np.mean(balls)) + s_t * (t - 21) + s_rh * (h - 50),
                        "per_ball": {f"B{i}": float(x) for i, x in enumerate(balls)},
                    }
                )
            )
        fit = fit_air(results, 21.0, 50.0, 0.0021, 0.00085)
        assert fit is not None
        d = np.array([1.2, -4.0])  # a bat test 1.2 C warmer, 4 % drier
        true = s_t * d[0] + s_rh * d[1]
        est = fit.cor_per_c * d[0] + fit.cor_per_pct_rh * d[1]
        var_t, cov, var_rh = fit.covariance
        u = math.sqrt(d @ np.array([[var_t, cov], [cov, var_rh]]) @ d)
        inside += abs(est - true) <= 2 * u
    assert 0.90 <= inside / trials <= 0.99, inside / trials


def test_a_spread_from_too_few_balls_is_not_called_measured() -> None:
    lot = BallLot(id="L", maker="m", model="x")
    two = result(0.52, 21, 50, sd=0.0001, n=2).model_copy(update={"sd_between_balls": 0.0001})
    terms = terms_from_lot(lot, [two])
    assert terms.sd_between_balls == BallTerms().sd_between_balls and "spread assumed" in terms.source
    six = result(0.52, 21, 50, sd=0.0011, n=6)
    assert terms_from_lot(lot, [six]).sd_between_balls == pytest.approx(0.0011)


def test_pooled_wear_weights_and_widens_for_disagreeing_runs() -> None:
    a = result(0.52, 21, 50, wear=-3.0e-4)
    b = result(0.52, 21, 50, wear=-3.2e-4)
    mean, u = pooled_wear([a, b]) or (0.0, 0.0)
    assert mean == pytest.approx(-3.1e-4)
    # each 1e-5: the mean's u 1e-5 / sqrt(2), times the Birge ratio sqrt(chi2 / 1) = sqrt(2)
    assert u == pytest.approx(1e-5, rel=1e-6)


def test_conditions_u_is_the_quadratic_form_of_the_covariance() -> None:
    cov = (4e-8, -1e-8, 9e-9)
    terms = BallTerms(conditions_measured=True, cor_per_c=0.0015, cor_per_pct_rh=-0.0006, air_cov=cov)
    hits = [HitBall("B1", 0, 22.0, 46.0), HitBall("B1", 1, 22.4, 45.0)]
    out = adjust(terms, hits, g=0.9)
    d = np.array([22.2 - 21.0, 45.5 - 50.0])
    sigma = np.array([[cov[0], cov[1]], [cov[1], cov[2]]])
    sensors = (0.0015 * terms.sensor_u_c) ** 2 + (0.0006 * terms.sensor_u_pct) ** 2  # the readings' own u
    assert out.u_conditions == pytest.approx(0.9 * math.sqrt(d @ sigma @ d + sensors))
    expected = [-0.9 * (0.0015 * (h.temp_c - 21) - 0.0006 * (h.rh_pct - 50)) for h in hits]
    assert list(out.corrections) == pytest.approx(expected)


def test_lot_tests_at_three_hours_measure_the_simulated_lab(tmp_path: object) -> None:
    """Ball-cor tests at three points of the `lab` scene's swing of air: the fitted wear per hit and
    the sensitivity along the swing agree with the scene's ball, computed from the collision model
    with the scene's stated constants (not from any fit)."""
    procedure = BallProcedure.load("ball-cor")
    lot = BallLot(
        id="AIR", maker="m", model="x", conditioning=Conditioning(temperature_c=21.0, humidity_pct=50.0)
    )
    scene = Scene.load("lab")
    env = next(e for e in scene.effects if e.kind == "environment")
    wear_cfg = next(e for e in scene.effects if e.kind == "ball_wear")
    with Store.open(f"{tmp_path}/lot.db") as store:
        store.register_lot(lot)
        for k in range(3):
            at = air_starting_at(env.period_s * (k + 0.25) / 3)
            run_ball_test(store, procedure, lot, sim_config("lab", target=("plate", None), effects=at))
        lot_now, results = store.ball_lot("AIR")
    terms = terms_from_lot(lot_now, results)
    assert terms.wear_measured and terms.conditions_measured
    ball = scene.ball

    def plate(scale: float) -> float:
        return rigid_cor(ball.model_copy(update={"c1": ball.c1 * scale}), NOMINAL_V)

    true_wear = plate(1 + wear_cfg.damping_per_hit) - plate(1.0)
    assert terms.wear_per_hit == pytest.approx(true_wear, rel=0.05)
    # along the swing: +1 C comes with -rh_swing/temp_swing % RH
    d = np.array([1.0, -env.rh_swing_pct / env.temp_swing_c])
    true_air = plate(1 + env.damping_per_c * d[0] + env.damping_per_pct_rh * d[1]) - plate(1.0)
    est = terms.cor_per_c * d[0] + terms.cor_per_pct_rh * d[1]
    var_t, cov, var_rh = terms.air_cov or (0.0, 0.0, 0.0)
    u = math.sqrt(d @ np.array([[var_t, cov], [cov, var_rh]]) @ d)
    assert abs(est - true_air) <= 3 * u + 1e-5, (est, true_air, u)
    assert u < 0.25 * abs(true_air)  # measured, not the prior's guess
