"""The streaming tracker: early announcements, hard corners, and equality with the batch result."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.core.devices import GateCrossing
from rig.measure.realtime import (
    InboundKnown,
    ReboundKnown,
    ShotTracker,
    ShotWindowClosed,
    SpeedWithdrawn,
    Update,
)
from rig.measure.speeds import ShotDataError, shot_speeds, split_passes
from tests.measure.shots import CFG, POS, shot_ticks


def feed(crossings: list[GateCrossing]) -> tuple[ShotTracker, list[list[Update]]]:
    tr = ShotTracker(CFG, POS)
    return tr, [tr.add(c) for c in crossings]


def last_said(updates: list[Update]) -> tuple[float | None, float | None]:
    v_in = v_out = None
    for u in updates:
        if isinstance(u, InboundKnown):
            v_in = u.v
        elif isinstance(u, ReboundKnown):
            v_out = u.v
        elif u.which == "inbound":
            v_in = None
        else:
            v_out = None
    return v_in, v_out


def test_inbound_known_before_the_bat_and_rebound_after_two_gates() -> None:
    ticks = shot_ticks(60.8, 11.0)
    tr, steps = feed(ticks)
    batch = shot_speeds(split_passes(ticks, CFG), POS, CFG)
    assert steps[:2] == [[], []]
    assert steps[2] == [InboundKnown(batch.inbound)]  # at gate 3, before any rebound crossing
    assert steps[3] == []
    assert steps[4] == [ReboundKnown(batch.rebound)]  # rebound through 3 and 2
    assert steps[5] == []  # gate 1 does not change the near-pair rebound
    assert tr.finish() == [] and tr.speeds == batch


def test_slow_rebound_uses_the_near_pair_and_finish_closes() -> None:
    ticks = shot_ticks(60.8, 0.3)[:5]  # 0.8 s to reach gate 2; gate 1 never reached
    tr, steps = feed(ticks)
    assert steps[4] == [ReboundKnown(pytest.approx(0.3, rel=1e-5))]
    assert tr.finish() == []
    with pytest.raises(ShotWindowClosed):
        tr.add(ticks[0])


def test_rebound_seen_only_at_gate_3_gives_nothing_until_finish() -> None:
    tr, steps = feed(shot_ticks(60.8, 11.0)[:4])
    assert steps[3] == []
    assert tr.finish() == [] and tr.speeds.rebound is None


def test_rebound_missing_gate_2_settles_on_the_span_at_gate_1() -> None:
    ticks = shot_ticks(60.8, 11.0)
    _tr, steps = feed([*ticks[:4], ticks[5]])
    assert steps[4] == [ReboundKnown(pytest.approx(11.0, rel=1e-5))]


def test_inbound_waits_for_gate_3_and_finish_falls_back_to_the_far_pair() -> None:
    ticks = shot_ticks(60.8, 11.0)
    tr, steps = feed(ticks[:2])  # gate 3 never broke
    assert steps == [[], []]
    assert tr.finish() == [InboundKnown(tr.speeds.inbound_far)]


def test_wrap_mid_shot_and_disorder() -> None:
    ticks = shot_ticks(60.8, 11.0, start=(1 << 32) - 30_000)
    order = [2, 1, 0, 4, 3, 5]
    shuffled = [ticks[i] for i in order]
    tr, steps = feed(shuffled)
    assert steps[1] == [InboundKnown(pytest.approx(60.8, rel=5e-5))]  # gates 3 and 2 in, either order
    assert steps[2] == []  # gate 1, late, changes nothing
    assert last_said([u for s in steps for u in s] + tr.finish())[1] == pytest.approx(11.0, rel=1e-5)


def test_equal_ticks_raise_the_typed_error_when_the_window_closes() -> None:
    tr = ShotTracker(CFG, POS)
    tr.add(GateCrossing(1, 100))
    tr.add(GateCrossing(2, 10_100))
    assert tr.add(GateCrossing(3, 10_100)) == []
    assert isinstance(tr.problem, ShotDataError) and "same tick" in str(tr.problem)
    with pytest.raises(ShotDataError, match="same tick"):
        tr.finish()


def test_a_transient_problem_is_withdrawn_then_resolved() -> None:
    # Found by Hypothesis: a stray equal tick makes one prefix uncomputable, a late event fixes it.
    events = [GateCrossing(1, 12_500_001), GateCrossing(1, 15_000_000), GateCrossing(2, 12_500_001)]
    tr, _steps = feed(events)
    assert tr.problem is not None
    tr.add(GateCrossing(2, 12_500_000))
    assert tr.problem is None
    assert tr.speeds == shot_speeds(split_passes([*events, GateCrossing(2, 12_500_000)], CFG), POS, CFG)
    tr.finish()


def test_near_equal_ticks_give_a_finite_speed() -> None:
    tr = ShotTracker(CFG, POS)
    tr.add(GateCrossing(1, 100))
    tr.add(GateCrossing(2, 10_100))
    assert tr.add(GateCrossing(3, 10_101)) == [InboundKnown(pytest.approx(2.5e6))]


def test_bad_geometry_refused_at_once() -> None:
    with pytest.raises(ShotDataError):
        ShotTracker(CFG, (0.25, 0.5, 0.75))


def test_late_event_withdraws_an_announcement() -> None:
    tr = ShotTracker(CFG, POS)
    assert tr.add(GateCrossing(2, 10_000)) == []
    assert tr.add(GateCrossing(3, 14_000)) == [InboundKnown(pytest.approx(625.0))]
    # a gate-3 break that was *earlier* makes the inbound pass just {3} (then 2 starts a rebound)
    assert tr.add(GateCrossing(3, 5_000)) == [SpeedWithdrawn("inbound")]
    assert tr.finish() == []
    assert tr.speeds == shot_speeds(split_passes(tr.crossings, CFG), POS, CFG)
    assert last_said([InboundKnown(625.0), SpeedWithdrawn("inbound")]) == (None, None)


@st.composite
def streams(draw: st.DrawFn) -> list[GateCrossing]:
    v_in = draw(st.floats(1.0, 150.0))
    v_out = draw(st.floats(0.05, 150.0))
    start = draw(st.integers(0, (1 << 32) - 1))
    ticks = shot_ticks(v_in, v_out, start=start)
    keep = draw(st.lists(st.booleans(), min_size=6, max_size=6))
    ticks = [t for t, k in zip(ticks, keep, strict=True) if k]
    extras = draw(st.lists(st.tuples(st.integers(1, 3), st.integers(-30_000, 30_000)), max_size=3))
    base = ticks[0].tick if ticks else start
    ticks += [GateCrossing(g, (base + d) % CFG.modulus) for g, d in extras]  # strays, doubles, equal ticks
    return draw(st.permutations(ticks))


@settings(max_examples=300)
@given(streams())
def test_tracker_equals_batch(crossings: list[GateCrossing]) -> None:
    try:
        batch = shot_speeds(split_passes(crossings, CFG), POS, CFG)
    except ShotDataError:
        tr, _ = feed(crossings)  # add() itself never raises for bad data
        with pytest.raises(ShotDataError):
            tr.finish()
        return
    tr, steps = feed(crossings)
    said = [u for s in steps for u in s] + tr.finish()
    assert tr.speeds == batch
    assert last_said(said) == (batch.inbound, batch.rebound)
    for u in said:
        assert not isinstance(u, InboundKnown | ReboundKnown) or (u.v > 0.0 and u.v < float("inf"))
