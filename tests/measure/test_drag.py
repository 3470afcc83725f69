"""The drag correction to the impact point: exact against a numerical flight and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rig.measure.drag import air_density, inbound_impact_speed, kappa, lab_air, phi, rebound_impact_speed
from rig.measure.model import ShotInputs, UncertaintyModel, jacobian, outputs
from rig.measure.uncertainty import budget, monte_carlo

RHO, CD, D, M = 1.2, 0.35, 0.0737, 0.145
GATES = (0.75, 0.50, 0.25)


def _flight_times(
    v_start: float, x_start: float, direction: int, k_drag: float, marks: tuple[float, ...]
) -> dict:
    """Numerically integrate dx/dt = direction v, dv/dt = -(rho Cd A / 2m) v^2; times at the marks."""

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        return [direction * y[1], -k_drag * y[1] ** 2]

    events = []
    for mark in marks:

        def hit(_t: float, y: np.ndarray, mark: float = mark) -> float:
            return y[0] - mark

        events.append(hit)
    sol = solve_ivp(
        rhs, (0.0, 1.0), [x_start, v_start], events=events, rtol=1e-12, atol=1e-14, method="DOP853"
    )
    return {mark: (sol.t_events[i][0], sol.y_events[i][0][1]) for i, mark in enumerate(marks)}


def test_inbound_and_rebound_speeds_at_the_impact_point_match_a_numerical_flight() -> None:
    k = float(kappa(RHO, CD, D, M))
    # inbound: launched 1.5 m out at 62 m/s; gates 2 and 3 then the impact point (x = 0)
    marks = _flight_times(62.0, 1.5, -1, k, (0.50, 0.25, 0.0))
    (t2, _), (t3, _), (_, v_hit) = marks[0.50], marks[0.25], marks[0.0]
    got = float(inbound_impact_speed(0.50, 0.25, t3 - t2, k))
    assert got == pytest.approx(v_hit, rel=1e-9)
    midpoint = (0.25 / (t3 - t2)) * math.exp(-k * 0.375)  # the approximation not used
    assert abs(got - v_hit) < abs(midpoint - v_hit) / 100
    assert got < 0.25 / (t3 - t2)  # the ball slows before the bat
    # rebound: leaves the impact point at 11 m/s, through gates 3 then 2
    marks = _flight_times(11.0, 0.0, 1, k, (0.25, 0.50))
    dt = marks[0.50][0] - marks[0.25][0]
    got = float(rebound_impact_speed(0.25, 0.50, dt, k))
    assert got == pytest.approx(11.0, rel=1e-9)
    assert got > 0.25 / dt  # the ball slows after the bat


def test_closed_form_flight_of_the_simulator_gives_back_the_speed() -> None:
    # the simulator's own closed form t(x) = (L/v0) expm1(x/L), v = v0 exp(-x/L)
    from rig.simulators.effects.drag import DragConfig
    from rig.simulators.scene import Scene

    scene = Scene.load("drag")
    cfg = DragConfig(drag_coefficient=CD, air_density=RHO)
    drag = cfg.build(scene, __import__("random").Random(0))
    v0, muzzle = 63.0, 1.5
    t_a, t_b = drag.time_to(muzzle - 0.75, v0), drag.time_to(muzzle - 0.25, v0)
    k = float(kappa(RHO, CD, cfg.ball_diameter_m, scene.ball.m1))
    assert float(inbound_impact_speed(0.75, 0.25, t_b - t_a, k)) == pytest.approx(
        drag.speed_at(muzzle, v0), rel=1e-12
    )


def test_no_drag_is_spacing_over_time_and_phi_is_continuous() -> None:
    assert float(inbound_impact_speed(0.5, 0.25, 0.004, 0.0)) == 0.25 / 0.004
    assert float(rebound_impact_speed(0.25, 0.5, 0.02, 0.0)) == 0.25 / 0.02
    for z in (1e-4 * (1 - 1e-9), 1e-4 * (1 + 1e-9)):  # either side of the series' switch
        assert float(phi(z)) == pytest.approx(-math.expm1(-z) / z, rel=1e-14)
        assert float(phi(-z)) == pytest.approx(math.expm1(z) / z, rel=1e-14)


def test_complex_step_jacobian_for_drag_inputs_matches_central_differences() -> None:
    shot = ShotInputs.ideal(
        60.8, 11.0, GATES, 1e-7, 0.56, 0.19, 0.145, cd_in=0.35, cd_out=0.5, air_density=1.19
    )
    J = jacobian(shot)
    p = shot.vector()
    for j in (13, 14, 15, 12):  # Cd_in, Cd_out, rho, ball mass (through kappa too)
        h = 1e-6 * max(abs(p[j]), 1.0)
        up, dn = p.copy(), p.copy()
        up[j] += h
        dn[j] -= h
        fd = (outputs(up, shot.gates) - outputs(dn, shot.gates)) / (2 * h)
        assert J[:, j] == pytest.approx(fd, rel=1e-5, abs=1e-12)


def test_ideal_times_with_drag_give_back_the_impact_speeds() -> None:
    shot = ShotInputs.ideal(
        60.8, 11.0, GATES, 1e-7, 0.56, 0.19, 0.145, cd_in=0.35, cd_out=0.5, air_density=1.19
    )
    out = outputs(shot.vector(), shot.gates)
    assert out[0] == pytest.approx(60.8, rel=1e-12) and out[1] == pytest.approx(11.0, rel=1e-12)


def test_monte_carlo_agrees_with_the_linear_budget_including_drag_and_air() -> None:
    model = UncertaintyModel()
    hits = [
        ShotInputs.ideal(60.8, v, GATES, 1e-7, 0.56, 0.19, 0.145, cd_in=0.35, cd_out=0.5, air_density=1.19)
        for v in (10.9, 11.0, 11.1)
    ]
    lin = budget(hits, model)
    mc = monte_carlo(hits, model, draws=200_000)
    for i, name in enumerate(lin.outputs):
        assert mc.u[i] == pytest.approx(lin.u_of(name), rel=0.03), name
    shares = dict(lin.ranked("bbcor"))
    assert shares["Cd_in"] > 0 and shares["Cd_out"] > 0 and shares["rho"] > 0


def _cipm_2007(t_c: float, rh_pct: float, p_kpa: float) -> float:
    """Density of moist air by the CIPM-2007 equation (Picard et al., Metrologia 45, 2008), CO2 400 ppm."""
    T, p = t_c + 273.15, p_kpa * 1000.0
    p_sv = math.exp(1.2378847e-5 * T**2 - 1.9121316e-2 * T + 33.93711047 - 6.3431645e3 / T)
    f = 1.00062 + 3.14e-8 * p + 5.6e-7 * t_c**2
    x_v = rh_pct / 100.0 * f * p_sv / p
    z = (
        1
        - p
        / T
        * (
            1.58123e-6
            - 2.9331e-8 * t_c
            + 1.1043e-10 * t_c**2
            + (5.707e-6 - 2.051e-8 * t_c) * x_v
            + (1.9898e-4 - 2.376e-6 * t_c) * x_v**2
        )
        + p**2 / T**2 * (1.83e-11 - 0.765e-8 * x_v**2)
    )
    m_a, m_v, r = 28.96546e-3, 18.01528e-3, 8.314472
    return p * m_a / (z * r * T) * (1 - x_v * (1 - m_v / m_a))


@pytest.mark.parametrize("t_c", [15.0, 21.0, 27.0])
@pytest.mark.parametrize("rh", [20.0, 50.0, 80.0])
def test_air_density_formula_against_cipm_2007(t_c: float, rh: float) -> None:
    ref = _cipm_2007(t_c, rh, 101.325)
    got = float(air_density(t_c, rh, 101.325))
    assert got == pytest.approx(ref, rel=1e-3)
    air = lab_air(t_c, rh, 101.325, 0.5, 5.0, 3.0)
    assert abs(got - ref) < 2 * air.u  # the stated u covers the formula's own error
    assert air.contributions["pressure"] == pytest.approx(3.0e3 / (287.058 * (t_c + 273.15)), rel=1e-9)
