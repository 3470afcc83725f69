"""Gate ticks to speeds: closed-form shots, counter wrap, disorder, doubled and missed triggers."""

from __future__ import annotations

import random

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core.devices import GateConfig, GateCrossing
from rig.measure.speeds import ShotDataError, pair_speed, shot_speeds, split_passes

CFG = GateConfig(gates=3, tick_ns=100.0, bits=32)
POS = (0.75, 0.50, 0.25)


def shot_ticks(v_in: float, v_out: float, start: int = 1000, cfg: GateConfig = CFG) -> list[GateCrossing]:
    """Exact crossings of a straight-line shot (no drag), ticks rounded to the counter."""
    times = [(POS[0] - x) / v_in for x in POS]  # inbound through 1, 2, 3
    t_hit = POS[0] / v_in
    times += [t_hit + x / v_out for x in (POS[2], POS[1], POS[0])]  # rebound through 3, 2, 1
    gates = [1, 2, 3, 3, 2, 1]
    return [
        GateCrossing(g, (start + round(t / cfg.tick_s)) % cfg.modulus)
        for g, t in zip(gates, times, strict=True)
    ]


def test_speeds_of_an_exact_shot() -> None:
    passes = split_passes(shot_ticks(60.8, 14.0), CFG)
    assert sorted(passes.inbound) == [1, 2, 3] and sorted(passes.rebound) == [1, 2, 3]
    sp = shot_speeds(passes, POS, CFG)
    # quantization: 0.1 us over ~4.1 ms is 2.5e-5 relative at most
    assert sp.inbound == pytest.approx(60.8, rel=5e-5)
    assert sp.inbound_far == pytest.approx(60.8, rel=5e-5)
    assert sp.rebound == pytest.approx(14.0, rel=1e-5)
    assert sp.rebound_far == pytest.approx(14.0, rel=1e-5)


@given(
    v_in=st.floats(5.0, 100.0),
    v_out=st.floats(1.0, 60.0),
    start=st.integers(0, (1 << 32) - 1),
)
def test_counter_wrap_anywhere_changes_nothing(v_in: float, v_out: float, start: int) -> None:
    sp = shot_speeds(split_passes(shot_ticks(v_in, v_out, start), CFG), POS, CFG)
    ref = shot_speeds(split_passes(shot_ticks(v_in, v_out, 1000), CFG), POS, CFG)
    assert sp == ref


def test_out_of_order_events_are_sorted_by_counter() -> None:
    crossings = shot_ticks(60.8, 14.0, start=(1 << 32) - 30_000)  # wraps between gates
    shuffled = crossings[:]
    random.Random(4).shuffle(shuffled)
    assert shot_speeds(split_passes(shuffled, CFG), POS, CFG) == shot_speeds(
        split_passes(crossings, CFG), POS, CFG
    )


def test_doubled_trigger_is_set_aside() -> None:
    crossings = shot_ticks(60.8, 14.0)
    double = GateCrossing(2, crossings[1].tick + 50)  # 5 us after the first break of gate 2
    passes = split_passes([*crossings[:2], double, *crossings[2:]], CFG)
    assert passes.extra == (double,)
    assert shot_speeds(passes, POS, CFG).inbound == pytest.approx(60.8, rel=5e-5)


def test_missed_middle_gate_falls_back_to_the_outer_pair() -> None:
    crossings = shot_ticks(60.8, 14.0)
    del crossings[4]  # rebound never seen at gate 2
    sp = shot_speeds(split_passes(crossings, CFG), POS, CFG)
    assert sp.rebound_near is None and sp.rebound_far is None
    assert sp.rebound == sp.rebound_span == pytest.approx(14.0, rel=1e-5)
    assert sp.inbound == pytest.approx(60.8, rel=5e-5)
    assert sp.inbound_span is None  # gate 2 saw the inbound ball: no fallback needed


def test_missed_outer_gate_leaves_a_hole_not_a_wrong_speed() -> None:
    crossings = shot_ticks(60.8, 14.0)
    del crossings[5]  # rebound never reached gate 1
    del crossings[4]  # nor gate 2
    sp = shot_speeds(split_passes(crossings, CFG), POS, CFG)
    assert sp.rebound is None


def test_slow_rebound_that_never_reaches_the_far_gate() -> None:
    crossings = shot_ticks(60.8, 3.0)[:5]  # the window closed before gate 1
    sp = shot_speeds(split_passes(crossings, CFG), POS, CFG)
    assert sp.rebound_far is None
    assert sp.rebound == pytest.approx(3.0, rel=1e-5)


def test_equal_timestamps_refused() -> None:
    with pytest.raises(ShotDataError, match="same tick"):
        pair_speed(GateCrossing(1, 500), GateCrossing(2, 500), 0.25, CFG)


def test_near_equal_timestamps_give_finite_large_speed() -> None:
    assert pair_speed(GateCrossing(1, 500), GateCrossing(2, 501), 0.25, CFG) == pytest.approx(2.5e6)


def test_unknown_gate_and_bad_geometry_refused() -> None:
    with pytest.raises(ShotDataError, match="gate 4"):
        split_passes([GateCrossing(4, 1)], CFG)
    with pytest.raises(ShotDataError, match="farthest first"):
        shot_speeds(split_passes([], CFG), (0.25, 0.5, 0.75), CFG)
