"""Each validity check triggered and not triggered, with stable codes."""

from __future__ import annotations

import math

import pytest

from rig.core.devices import GateCrossing, Recoil
from rig.core.units import MPH
from rig.measure.speeds import GatePasses, ShotSpeeds, shot_speeds, split_passes
from rig.measure.validity import (
    Code,
    ValidityLimits,
    check_shot,
    expected_pair_ratio,
    expected_recoil,
    is_valid,
)
from tests.measure.shots import BALL, CFG, MOI, POS, Q, shot_ticks

FULL = split_passes(shot_ticks(60.8, 11.0), CFG)


def speeds(v_in: float | None = 60.8, v_out: float | None = 11.0, far: float | None = None) -> ShotSpeeds:
    """Speeds with the inbound far pair consistent with 0.3 %/m drag unless given."""
    if far is None and v_in is not None:
        far = v_in / expected_pair_ratio(POS, 0.003)
    return ShotSpeeds(far, v_in, v_out, v_out)


def codes(sp: ShotSpeeds, passes: GatePasses = FULL, **kw) -> list[Code]:
    args = {"target_speed_m_s": 60.8, "recoil": None, "limits": ValidityLimits()} | kw
    return [
        r.code
        for r in check_shot(
            sp, passes, args["target_speed_m_s"], args["recoil"], Q, MOI, BALL, args["limits"]
        )
    ]


def test_codes_are_stable() -> None:
    assert {c.value for c in Code} == {
        "PAIRS_DISAGREE", "REBOUND_FAST", "SPEED_OUT_OF_TOLERANCE", "NO_INBOUND", "NO_REBOUND",
        "RECOIL_MISMATCH", "DOUBLE_TRIGGER", "MISSED_GATE",
    }  # fmt: skip


def test_documented_defaults() -> None:
    lim = ValidityLimits()
    assert lim.pair_tolerance_rel == 0.01 and lim.drag_per_m == 0.003
    assert lim.speed_tolerance_m_s == pytest.approx(1.0 * MPH) and lim.recoil_tolerance_rel == 0.10


def test_a_clean_shot_has_no_reasons() -> None:
    sp = shot_speeds(FULL, POS, CFG)  # no drag in the synthetic ticks: 0.075 % inside the 1 % tolerance
    assert check_shot(sp, FULL, 60.8, None, Q, MOI, BALL) == []
    omega = expected_recoil(60.8, 11.0, Q, MOI, BALL)
    assert codes(speeds(), recoil=Recoil(omega * 1.05)) == []


def test_pairs_disagree() -> None:
    assert Code.PAIRS_DISAGREE in codes(speeds(far=60.8 * 1.02))
    assert Code.PAIRS_DISAGREE not in codes(speeds(far=60.8 * 1.008))
    reason = check_shot(speeds(far=60.8 * 1.02), FULL, 60.8, None, Q, MOI, BALL)[0]
    assert reason.invalidates and "gates 1-2" in reason.message


def test_drag_allowance_is_applied_and_configurable() -> None:
    tight = ValidityLimits(pair_tolerance_rel=2e-4)
    assert codes(speeds(), limits=tight) == []  # the drag loss between the pairs is expected
    no_drag = ValidityLimits(pair_tolerance_rel=2e-4, drag_per_m=0.0)
    assert codes(speeds(), limits=no_drag) == [Code.PAIRS_DISAGREE]
    assert expected_pair_ratio(POS, 0.003) == pytest.approx(math.exp(-0.003 * 0.25))


def test_rebound_fast() -> None:
    assert Code.REBOUND_FAST in codes(speeds(v_out=60.8))
    assert Code.REBOUND_FAST not in codes(speeds(v_out=60.7))


def test_speed_out_of_tolerance() -> None:
    assert codes(speeds(v_in=60.8 + 0.5)) == [Code.SPEED_OUT_OF_TOLERANCE]
    assert codes(speeds(v_in=60.8 - 0.5)) == [Code.SPEED_OUT_OF_TOLERANCE]
    assert codes(speeds(v_in=60.8 + 0.4)) == []
    assert codes(speeds(v_in=65.0), target_speed_m_s=None) == []
    assert codes(speeds(v_in=61.5), limits=ValidityLimits(speed_tolerance_m_s=1.0)) == []


def test_no_inbound_and_no_rebound() -> None:
    assert codes(speeds(v_out=None)) == [Code.NO_REBOUND]
    assert Code.NO_INBOUND in codes(ShotSpeeds(None, None, 11.0, 11.0))


def test_recoil_mismatch_only_when_measured() -> None:
    omega = expected_recoil(60.8, 11.0, Q, MOI, BALL)
    assert omega == pytest.approx(BALL * Q * 71.8 / MOI)
    assert codes(speeds(), recoil=Recoil(omega * 1.15)) == [Code.RECOIL_MISMATCH]
    assert codes(speeds(), recoil=Recoil(omega * 0.85)) == [Code.RECOIL_MISMATCH]
    assert codes(speeds(), recoil=Recoil(omega * 0.95)) == []
    assert codes(speeds(), recoil=None) == []


def test_double_trigger_is_a_note_unless_configured() -> None:
    ticks = shot_ticks(60.8, 11.0)
    passes = split_passes([*ticks[:2], GateCrossing(2, ticks[1].tick + 40), *ticks[2:]], CFG)
    sp = shot_speeds(passes, POS, CFG)
    reasons = check_shot(sp, passes, 60.8, None, Q, MOI, BALL)
    assert [r.code for r in reasons] == [Code.DOUBLE_TRIGGER] and is_valid(reasons)
    strict = check_shot(sp, passes, 60.8, None, Q, MOI, BALL, ValidityLimits(double_trigger_invalidates=True))
    assert not is_valid(strict)


def test_missed_gates() -> None:
    ticks = shot_ticks(60.8, 11.0)
    no_in_1 = split_passes(ticks[1:], CFG)  # inbound gate 1 missed: no cross-check possible
    reasons = check_shot(shot_speeds(no_in_1, POS, CFG), no_in_1, 60.8, None, Q, MOI, BALL)
    assert [r.code for r in reasons] == [Code.MISSED_GATE] and not is_valid(reasons)
    lenient = ValidityLimits(require_inbound_cross_check=False)
    assert is_valid(check_shot(shot_speeds(no_in_1, POS, CFG), no_in_1, 60.8, None, Q, MOI, BALL, lenient))
    short = split_passes(ticks[:5], CFG)  # slow rebound never reached gate 1: normal, no reason
    assert check_shot(shot_speeds(short, POS, CFG), short, 60.8, None, Q, MOI, BALL) == []
    hole = split_passes([*ticks[:4], ticks[5]], CFG)  # rebound seen at 3 and 1, not at 2: a note
    reasons = check_shot(shot_speeds(hole, POS, CFG), hole, 60.8, None, Q, MOI, BALL)
    assert [r.code for r in reasons] == [Code.MISSED_GATE] and is_valid(reasons)
