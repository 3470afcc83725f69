"""The learned aim: a running mean of the shots' speed ratios, then an exponential mean."""

from __future__ import annotations

import random
import statistics

from hypothesis import given
from hypothesis import strategies as st

from rig.protocols.outcome import AIM_GAIN_MIN, learned_aim

TARGET = 60.8


def _teach(ratios: list[float]) -> list[float]:
    """The aim factor after each shot, when the cannon gives `ratio` times the aimed speed."""
    factor, out = 1.0, []
    for taught, r in enumerate(ratios):
        at_impact = r * TARGET / factor  # aimed TARGET / factor, the cannon gives r times that
        factor = learned_aim(factor, TARGET, at_impact, taught)
        out.append(factor)
    return out


def test_first_shots_give_the_mean_of_their_ratios() -> None:
    ratios = [0.99, 1.004, 0.987, 0.995, 1.001]  # 1/(k+1) >= 0.2 for the first five
    for k, factor in enumerate(_teach(ratios)):
        assert abs(factor - statistics.mean(ratios[: k + 1])) < 1e-12


def test_a_steady_cannon_is_learned_in_one_shot_and_kept() -> None:
    assert all(abs(f - 0.985) < 1e-12 for f in _teach([0.985] * 20))


@given(st.lists(st.floats(0.8, 1.2), min_size=1, max_size=40))
def test_the_factor_stays_within_the_ratios_seen(ratios: list[float]) -> None:
    for k, factor in enumerate(_teach(ratios)):
        assert min(ratios[: k + 1]) - 1e-12 <= factor <= max(ratios[: k + 1]) + 1e-12


def test_the_aim_adds_little_to_the_cannons_own_scatter() -> None:
    """Monte Carlo: speeds at the bat scatter about sqrt(1 + g/(2 - g)) times the cannon's own
    (g = AIM_GAIN_MIN: 1.054) once the running mean has given way; the old fixed gain of 1/2 gave
    1.155, and more shots fell outside the speed window."""
    rng, sigma = random.Random(5), 0.005
    factor, spread = 1.0, []
    for taught in range(20000):
        r = 0.99 * (1.0 + rng.gauss(0.0, sigma))
        at_impact = r * TARGET / factor
        if taught > 50:
            spread.append(at_impact / TARGET - 1.0)
        factor = learned_aim(factor, TARGET, at_impact, taught)
    expected = sigma * (1.0 + AIM_GAIN_MIN / (2.0 - AIM_GAIN_MIN)) ** 0.5
    assert abs(statistics.pstdev(spread) / expected - 1.0) < 0.03
    assert abs(statistics.mean(spread)) < 5 * sigma / len(spread) ** 0.5


def test_a_resumed_run_learns_its_aim_afresh() -> None:
    """A resumed session may have a repaired cannon: the factor and its count start again."""
    from rig.core import events as ev
    from rig.core.run_state import fold

    shot = {"index": 0, "purpose": "valid", "location_in": 6.0}
    taught = {"index": 0, "metric": 0.49, "aim_factor": 0.98, "aim_shots": 3}
    before = fold([ev.from_payload(ev.SHOT_REQUESTED, shot), ev.from_payload(ev.SHOT_MEASURED, taught)])
    assert (before.aim_factor, before.aim_shots) == (0.98, 3)
    resumed = ev.RunResumed(shots_so_far=1)
    after = fold(
        [ev.from_payload(ev.SHOT_REQUESTED, shot), ev.from_payload(ev.SHOT_MEASURED, taught), resumed]
    )
    assert (after.aim_factor, after.aim_shots) == (1.0, 0)
