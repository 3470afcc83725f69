"""Clamp driver specifics: confirmation events, stage position, pendulum period, recoil."""

from __future__ import annotations

import time

import pytest

from rig.core.devices import Recoil
from rig.core.errors import DeviceError, DeviceRefused, DeviceTimeout, GarbledReply, ParameterError
from rig.drivers.clamp.driver import ClampDriver
from tests.drivers.cases import FAST
from tests.drivers.fakeport import cmd, err, event, ok, scripted

KW = FAST[ClampDriver]


def test_clamp_waits_for_the_lock_sensor_not_for_the_ok() -> None:
    script = [(cmd(1, "CLAMP"), ok(1) + event("LOCK", {"L": 0}))]
    with scripted(ClampDriver, script, lock_timeout_s=1.0) as (clamp, port):
        port.inject(event("LOCK", {"L": 1}), delay_s=0.05)
        start = time.monotonic()
        clamp.clamp()
        assert time.monotonic() - start >= 0.04


def test_lock_never_confirmed_times_out() -> None:
    script = [(cmd(1, "CLAMP"), ok(1) + event("LOCK", {"L": 0}))]
    with scripted(ClampDriver, script, **KW) as (clamp, _), pytest.raises(DeviceTimeout, match="LOCK"):
        clamp.clamp()


def test_malformed_lock_event_is_garbled() -> None:
    script = [(cmd(1, "RELEASE"), ok(1) + event("LOCK", {"L": "open"}))]
    with scripted(ClampDriver, script, **KW) as (clamp, _), pytest.raises(GarbledReply, match="LOCK event"):
        clamp.release()


def test_stage_stopping_short_is_a_device_error() -> None:
    script = [(cmd(1, "MOVE", "450.0"), ok(1) + event("POS", {"MM": 300.0}))]
    with (
        scripted(ClampDriver, script, **KW) as (clamp, _),
        pytest.raises(DeviceError, match="stopped at 300"),
    ):
        clamp.move_to(450.0)


def test_stage_busy_is_refused() -> None:
    script = [(cmd(1, "MOVE", "450"), err(1, "BUSY", "moving"))]
    with scripted(ClampDriver, script, **KW) as (clamp, _), pytest.raises(DeviceRefused, match="BUSY moving"):
        clamp.move_to(450)


def test_position_out_of_travel_is_refused_before_sending() -> None:
    with scripted(ClampDriver, [], **KW) as (clamp, port):
        with pytest.raises(ParameterError, match="MOVE"):
            clamp.move_to(950.0)
        with pytest.raises(ParameterError, match="SWING"):
            clamp.measure_period(0)
        assert port.written == b""


def test_swing_deadline_grows_with_the_cycles() -> None:
    script = [(cmd(1, "SWING", 2), ok(1))]
    kw = {**KW, "swing_timeout_s": 0.05, "swing_cycle_timeout_s": 0.05}
    with scripted(ClampDriver, script, **kw) as (clamp, _):
        start = time.monotonic()
        with pytest.raises(DeviceTimeout, match=r"no PERIOD event within 0\.15 s"):
            clamp.measure_period(2)
        assert time.monotonic() - start >= 0.15


def test_swing_refused_while_unlocked() -> None:
    script = [(cmd(1, "SWING", 5), err(1, "STATE", "grip open"))]
    with scripted(ClampDriver, script, **KW) as (clamp, _), pytest.raises(DeviceRefused) as info:
        clamp.measure_period(5)
    assert info.value.code == "STATE"


def test_bad_period_is_garbled() -> None:
    script = [(cmd(1, "SWING", 5), ok(1) + event("PERIOD", {"US": -3, "AMP": 5.0, "N": 5}))]
    with scripted(ClampDriver, script, **KW) as (clamp, _), pytest.raises(GarbledReply, match="non-positive"):
        clamp.measure_period(5)


def test_next_recoil_returns_the_next_one_or_none() -> None:
    with scripted(ClampDriver, [], **KW) as (clamp, port):
        port.inject(event("RECOIL", {"W": 12.5}), delay_s=0.02)
        assert clamp.next_recoil(1.0) == Recoil(12.5)
        start = time.monotonic()
        assert clamp.next_recoil(0.05) is None
        assert 0.05 <= time.monotonic() - start < 0.2


def test_malformed_recoil_is_garbled() -> None:
    with scripted(ClampDriver, [], **KW) as (clamp, port):
        port.inject(event("RECOIL", {"OMEGA": 3}))
        with pytest.raises(GarbledReply, match="RECOIL event"):
            clamp.next_recoil(0.1)


def test_bad_status_is_garbled() -> None:
    script = [(cmd(1, "STATUS"), ok(1, {"LOCK": 1, "POS": 500.0, "MOVING": 0}))]
    with scripted(ClampDriver, script, **KW) as (clamp, _), pytest.raises(GarbledReply, match="DEG"):
        clamp.status()


def test_a_clamp_without_an_encoder_waits_for_no_recoil() -> None:
    """recoil_encoder = false: a RECOIL that cannot come is not waited for (5 s asked, none spent)."""
    with scripted(ClampDriver, [], recoil_encoder=False, **KW) as (clamp, _):
        start = time.monotonic()
        assert clamp.next_recoil(5.0) is None
        assert time.monotonic() - start < 1.0


def test_the_recoil_encoder_option_comes_from_the_rig_config_and_the_scene() -> None:
    """A scene without the recoil effect configures its clamp without an encoder; one with it (the
    lab scene), and any config that does not say, with one; a stranger option is refused in one line."""
    from rig.core.config import RigConfig
    from rig.core.errors import ConfigError
    from rig.session import RigSession, sim_config

    assert sim_config("ideal").device("clamp").options == {"recoil_encoder": False}
    assert sim_config("lab").device("clamp").options == {}
    with RigSession.open(sim_config("ideal")) as session:
        assert isinstance(session.clamp, ClampDriver) and session.clamp.recoil_encoder is False
    with RigSession.open(sim_config("lab")) as session:
        assert isinstance(session.clamp, ClampDriver) and session.clamp.recoil_encoder is True
    odd = sim_config("ideal").model_dump()
    odd["devices"]["clamp"]["options"] = {"encoder": False}
    with pytest.raises(ConfigError, match=r"\[devices.clamp\] driver does not know option 'encoder'"):
        RigSession.open(RigConfig.model_validate(odd))
