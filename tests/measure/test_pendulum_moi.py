"""The pendulum MOI from the swing timings (rig.measure.moi.pendulum_moi), not assembled in the runner.

Checked against the simulator's forward formula (a round trip through rig.simulators.physics) and
against a closed form: a point mass on the pivot at d = g / pi^2 swings with T0 = 2 s exactly,
and its MOI is m d^2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.config import Pendulum
from rig.core.devices import PendulumPeriod
from rig.core.errors import ParameterError
from rig.core.units import G_STANDARD
from rig.measure.moi import MoiBudget, pendulum_moi
from rig.simulators.physics import pendulum_period

PEND = Pendulum(gravity_m_s2=G_STANDARD)


@pytest.mark.parametrize(
    ("moi", "mass", "balance_from_knob_m", "amp_deg"),
    [(0.19, 0.85, 0.56, 5.0), (0.25, 0.88, 0.60, 12.0), (0.05, 0.57, 0.40, 1.0), (0.6, 1.4, 0.7, 0.0)],
)
def test_round_trip_through_the_simulators_forward_formula(
    moi: float, mass: float, balance_from_knob_m: float, amp_deg: float
) -> None:
    lever = balance_from_knob_m - PIVOT_FROM_KNOB_M
    t = pendulum_period(moi, mass, lever, math.radians(amp_deg))
    timings = [PendulumPeriod(t, amp_deg, 10), PendulumPeriod(t, amp_deg, 10)]
    reading, budget = pendulum_moi(timings, mass, balance_from_knob_m, PEND)
    assert budget.moi_kgm2 == pytest.approx(moi, rel=1e-12)
    assert reading.lever_m == pytest.approx(lever, rel=1e-15)
    assert reading.periods_s == (t, t)
    assert budget.source == "pendulum"


def test_point_mass_closed_form() -> None:
    g, m = 9.81, 0.9
    d = g / math.pi**2  # T0 = 2 pi sqrt(d / g) = 2 s
    pend = Pendulum(gravity_m_s2=g)
    for amp in (0.0, 10.0):
        t = 2.0 * (1.0 + math.radians(amp) ** 2 / 16.0)
        _, budget = pendulum_moi([PendulumPeriod(t, amp, 20)], m, PIVOT_FROM_KNOB_M + d, pend)
        assert budget.moi_kgm2 == pytest.approx(m * d * d, rel=1e-12)


def test_mean_of_periods_and_amplitudes() -> None:
    g, m = 9.81, 0.9
    d = g / math.pi**2
    # periods 1.9 and 2.1 s average to 2 s; amplitudes 0 and 0 deg
    timings = [PendulumPeriod(1.9, 0.0, 10), PendulumPeriod(2.1, 0.0, 10)]
    reading, budget = pendulum_moi(timings, m, PIVOT_FROM_KNOB_M + d, Pendulum(gravity_m_s2=g))
    assert budget.moi_kgm2 == pytest.approx(m * d * d, rel=1e-12)
    assert reading.cycles == 10 and reading.amplitude_deg == 0.0


def test_a_balance_point_at_or_behind_the_pivot_is_refused() -> None:
    with pytest.raises(ParameterError, match="balance"):
        pendulum_moi([PendulumPeriod(1.5, 5.0, 10)], 0.85, PIVOT_FROM_KNOB_M, PEND)
    with pytest.raises(ParameterError, match="timing"):
        pendulum_moi([], 0.85, 0.5, PEND)


def test_a_host_computed_periods_uncertainty_enters_the_budget_as_its_own_row() -> None:
    """A swing sensor's periods come with the host fit's u: the budget adds T_host, u of the mean of
    independent fits (sqrt(sum u_i^2) / r) times dI/dT = 2 I / T, beyond what the timings' scatter
    shows; with equal periods (scatter 0) that is all of it, and the combined u grows by it in
    quadrature; a timer's periods (no u) add no such row."""
    g, m = 9.81, 0.9
    d = g / math.pi**2  # T0 = 2 s at zero amplitude
    pend = Pendulum(gravity_m_s2=g)
    timed = [PendulumPeriod(2.0, 0.0, 10), PendulumPeriod(2.0, 0.0, 10)]
    fitted = [PendulumPeriod(2.0, 0.0, 10, u_s=3e-4), PendulumPeriod(2.0, 0.0, 10, u_s=4e-4)]
    _, plain = pendulum_moi(timed, m, PIVOT_FROM_KNOB_M + d, pend)
    reading, host = pendulum_moi(fitted, m, PIVOT_FROM_KNOB_M + d, pend)
    assert reading.host_u_s == (3e-4, 4e-4)
    assert "T_host" not in {i.name for i in plain.inputs}
    (row,) = [i for i in host.inputs if i.name == "T_host"]
    assert row.u == pytest.approx(5e-4 / 2, rel=1e-12)
    moi = m * d * d
    assert row.u_moi == pytest.approx(2 * moi / 2.0 * 2.5e-4, rel=1e-12)
    assert host.u_kgm2 == pytest.approx(math.hypot(plain.u_kgm2, row.u_moi), rel=1e-12)


def _period_u(budget: MoiBudget) -> float:
    """u of the mean period from the budget's period rows (T_res, T_scatter, T_host) combined."""
    rows = [i for i in budget.inputs if i.name.startswith("T_")]
    assert {i.name for i in rows} <= {"T_res", "T_scatter", "T_host"}
    return math.sqrt(sum(i.u**2 for i in rows))


def test_the_host_u_and_the_scatter_combine_to_the_larger_not_their_sum() -> None:
    """The scatter of r timings already holds the fits' random error: T_host is only the host u
    beyond it, so T_scatter and T_host together are max(u_scatter, u_host)."""
    g, m = 9.81, 0.9
    d = g / math.pi**2
    pend = Pendulum(gravity_m_s2=g, timer_resolution_s=1e-9)
    spread = [2.0 - 1e-3, 2.0, 2.0 + 1e-3]  # s = 1e-3, u_scatter = 1e-3 / sqrt(3)
    u_scatter = 1e-3 / math.sqrt(3.0)
    for host_u, expected in ((1e-4, u_scatter), (3e-3, 3e-3 / math.sqrt(3.0))):
        timings = [PendulumPeriod(p, 0.0, 10, u_s=host_u) for p in spread]
        _, budget = pendulum_moi(timings, m, PIVOT_FROM_KNOB_M + d, pend)
        rows = {i.name: i.u for i in budget.inputs}
        assert math.hypot(rows["T_scatter"], rows["T_host"]) == pytest.approx(expected, rel=1e-9)
    (host,) = [i for i in budget.inputs if i.name == "T_host"]
    assert "beyond their scatter" in host.what


@pytest.mark.parametrize("r", [3, 5])
def test_the_period_u_covers_the_fit_noise_once_monte_carlo(r: int) -> None:
    """Monte Carlo independent of the budget code: each draw is r periods = truth + the fit's noise
    (normal, sigma known), each reported with host u = sigma, as a swing sensor's fits are. Over
    many draws (estimated T - truth) / u_T, with u_T from the budget's period rows combined, must
    have an SD near 1: within 0.85-1.15 (expected about 0.92-0.93 for r = 3 and 5: u_T is
    max(s, sigma) / sqrt(r), a little above sigma / sqrt(r) on average). Counting the fit's error
    twice (T_host = sigma / sqrt(r) in full beside the scatter) gave about 0.77 and 0.74."""
    g, m, truth, sigma = 9.81, 0.9, 2.0, 2e-4
    d = g / math.pi**2
    pend = Pendulum(gravity_m_s2=g, timer_resolution_s=1e-9)  # T_res negligible beside sigma
    rng = np.random.default_rng(20250611 + r)
    draws = 4000
    z = np.empty(draws)
    for k, periods in enumerate(truth + rng.normal(0.0, sigma, (draws, r))):
        timings = [PendulumPeriod(float(p), 0.0, 10, u_s=sigma) for p in periods]
        _, budget = pendulum_moi(timings, m, PIVOT_FROM_KNOB_M + d, pend)
        z[k] = (float(np.mean(periods)) - truth) / _period_u(budget)
    sd = float(np.std(z, ddof=1))
    print(f"\nr = {r}: SD of (T - truth) / u_T over {draws} draws: {sd:.3f}")
    assert 0.85 <= sd <= 1.15, sd
