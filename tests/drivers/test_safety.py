"""SAFETY: the driver never sends ARM or FIRE when the state table says no.

The refusal is decided on a fresh STATUS; the only bytes the port may then have seen are that
STATUS command. Hypothesis walks every state and every open-interlock combination.
"""

from __future__ import annotations

import itertools

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.core.devices import CannonState
from rig.core.errors import SafetyRefusal
from rig.drivers.cannon.driver import CannonDriver
from tests.drivers.cases import FAST, cannon_status
from tests.drivers.fakeport import cmd, ok, scripted

interlocks = st.tuples(st.booleans(), st.booleans(), st.booleans())
open_interlocks = interlocks.filter(lambda ilk: not all(ilk))  # the 7 unsafe combinations
states = st.sampled_from(list(CannonState))
pressures = st.floats(0.0, 1000.0)
safety = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def refused(call: str, state: CannonState, ilk: tuple[bool, bool, bool], p: float, setpoint: float) -> bytes:
    fields = cannon_status(state.value, p, setpoint, *ilk)
    with (
        scripted(CannonDriver, [(cmd(1, "STATUS"), ok(1, fields))], **FAST[CannonDriver]) as (cannon, port),
        pytest.raises(SafetyRefusal) as info,
    ):
        getattr(cannon, call)()
    assert info.value.device == "cannon"
    assert f"{call.upper()} not sent" in str(info.value)
    assert port.verbs_written() == ["STATUS"]
    return port.written


@safety
@given(states, open_interlocks, pressures)
def test_fire_with_any_interlock_open_is_refused_unsent(state, ilk, p) -> None:
    written = refused("fire", state, ilk, p, p)
    assert b"FIRE" not in written


@safety
@given(states.filter(lambda s: s is not CannonState.ARMED), interlocks, pressures)
def test_fire_unless_armed_is_refused_unsent(state, ilk, p) -> None:
    assert b"FIRE" not in refused("fire", state, ilk, p, p)


@safety
@given(states, open_interlocks, pressures)
def test_arm_with_any_interlock_open_is_refused_unsent(state, ilk, p) -> None:
    assert b"ARM" not in refused("arm", state, ilk, p, p)


@safety
@given(states.filter(lambda s: s is not CannonState.SAFE), interlocks, pressures)
def test_arm_unless_safe_is_refused_unsent(state, ilk, p) -> None:
    assert b"ARM" not in refused("arm", state, ilk, p, p)


@safety
@given(st.floats(1.0, 1000.0), st.floats(0.0, 2.0).filter(lambda r: abs(r - 1) > 0.0101))
def test_arm_away_from_the_setpoint_is_refused_unsent(setpoint, ratio) -> None:
    assert b"ARM" not in refused("arm", CannonState.SAFE, (True, True, True), setpoint * ratio, setpoint)


def test_the_open_interlocks_are_named() -> None:
    fields = cannon_status("ARMED", door=False, estop=False)
    with (
        scripted(CannonDriver, [(cmd(1, "STATUS"), ok(1, fields))]) as (cannon, _),
        pytest.raises(SafetyRefusal, match="interlock open: door, estop"),
    ):
        cannon.fire()


def test_fire_is_sent_only_when_armed_with_every_interlock_closed() -> None:
    script = [(cmd(1, "STATUS"), ok(1, cannon_status("ARMED"))), (cmd(2, "FIRE"), ok(2) + b"")]
    with scripted(CannonDriver, script, fire_timeout_s=0.01) as (cannon, port):
        with pytest.raises(Exception, match="FIRED"):
            cannon.fire()  # no FIRED event scripted: only the sending is under test here
        assert port.verbs_written() == ["STATUS", "FIRE"]


@pytest.mark.parametrize("call", ["fire", "arm"])
@pytest.mark.parametrize("state", list(CannonState))
@pytest.mark.parametrize("ilk", [c for c in itertools.product((True, False), repeat=3) if not all(c)])
def test_every_open_interlock_combination_in_every_state(call, state, ilk) -> None:
    assert call.upper().encode() not in refused(call, state, ilk, 420.0, 420.0)
