"""Cannon driver specifics: waiting for READY and FIRED, faults, parse errors."""

from __future__ import annotations

import time

import pytest

from rig.core.errors import DeviceError, DeviceRefused, DeviceTimeout, GarbledReply, ParameterError
from rig.drivers.cannon.driver import CannonDriver
from tests.drivers.cases import FAST, cannon_status
from tests.drivers.fakeport import cmd, err, event, ok, scripted

KW = FAST[CannonDriver]


def safe_status(seq: int = 1) -> tuple[bytes, bytes]:
    """The fresh STATUS the driver asks before PSET, answered SAFE."""
    return (cmd(seq, "STATUS"), ok(seq, cannon_status()))


def test_ready_before_the_ok_is_not_missed() -> None:
    script = [safe_status(), (cmd(2, "PSET", "420.0"), event("READY", {"P": 420.0}) + ok(2))]
    with scripted(CannonDriver, script, **KW) as (cannon, _):
        cannon.set_pressure(420.0)


def test_ready_arriving_later_is_waited_for() -> None:
    with scripted(CannonDriver, [safe_status(), (cmd(2, "PSET", "420.0"), ok(2))], ready_timeout_s=1.0) as (
        cannon,
        port,
    ):
        port.inject(event("READY", {"P": 421.0}), delay_s=0.05)
        cannon.set_pressure(420.0)


def test_ready_for_an_older_setpoint_is_skipped() -> None:
    script = [
        safe_status(),
        (cmd(2, "PSET", "420.0"), ok(2) + event("READY", {"P": 300.0}) + event("READY", {"P": 418.0})),
    ]
    with scripted(CannonDriver, script, **KW) as (cannon, _):
        cannon.set_pressure(420.0)
    script = [safe_status(), (cmd(2, "PSET", "420.0"), ok(2) + event("READY", {"P": 300.0}))]
    with scripted(CannonDriver, script, **KW) as (cannon, _), pytest.raises(DeviceTimeout, match="READY"):
        cannon.set_pressure(420.0)


def test_zero_setpoint_takes_any_ready() -> None:
    with scripted(
        CannonDriver, [safe_status(), (cmd(2, "PSET", "0"), ok(2) + event("READY", {"P": 0.4}))], **KW
    ) as (c, _):
        c.set_pressure(0)


def test_fault_while_filling_is_a_device_error() -> None:
    script = [safe_status(), (cmd(2, "PSET", "420.0"), ok(2) + event("FAULT", {"CODE": "SENSOR"}))]
    with (
        scripted(CannonDriver, script, **KW) as (c, _),
        pytest.raises(DeviceError, match="SENSOR after PSET"),
    ):
        c.set_pressure(420.0)


def test_ready_without_pressure_is_garbled() -> None:
    script = [safe_status(), (cmd(2, "PSET", "420.0"), ok(2) + event("READY"))]
    with scripted(CannonDriver, script, **KW) as (c, _), pytest.raises(GarbledReply, match="READY event"):
        c.set_pressure(420.0)


@pytest.mark.parametrize("kpa", [-1.0, 1000.5, float("nan"), float("inf")])
def test_pressure_out_of_range_is_refused_before_sending(kpa: float) -> None:
    with scripted(CannonDriver, [], **KW) as (cannon, port):
        with pytest.raises(ParameterError, match="PSET"):
            cannon.set_pressure(kpa)
        assert port.written == b""


def test_device_refusing_pset_though_status_said_safe() -> None:
    script = [safe_status(), (cmd(2, "PSET", "420.0"), err(2, "STATE", "not SAFE"))]
    with scripted(CannonDriver, script, **KW) as (c, _), pytest.raises(DeviceRefused) as info:
        c.set_pressure(420.0)
    assert info.value.code == "STATE"


def armed_status(seq: int = 1) -> tuple[bytes, bytes]:
    return (cmd(seq, "STATUS"), ok(seq, cannon_status("ARMED")))


def test_fired_arriving_later_gives_the_shot_number() -> None:
    with scripted(CannonDriver, [armed_status(), (cmd(2, "FIRE"), ok(2))], fire_timeout_s=1.0) as (c, port):
        port.inject(event("FIRED", {"SHOT": 12}), delay_s=0.05)
        assert c.fire() == 12


def test_a_fired_event_kept_from_before_is_not_taken_for_this_shot() -> None:
    script = [armed_status(), (cmd(2, "FIRE"), ok(2) + event("FIRED", {"SHOT": 8}))]
    with scripted(CannonDriver, script, **KW) as (cannon, port):
        port.inject(event("FIRED", {"SHOT": 7}))
        time.sleep(0.03)
        assert cannon.fire() == 8


def test_no_fired_event_times_out() -> None:
    with (
        scripted(CannonDriver, [armed_status(), (cmd(2, "FIRE"), ok(2))], **KW) as (c, _),
        pytest.raises(DeviceTimeout, match=r"no FIRED/FAULT event within 0\.1 s"),
    ):
        c.fire()


def test_misfire_is_a_device_error() -> None:
    script = [armed_status(), (cmd(2, "FIRE"), ok(2) + event("FAULT", {"CODE": "MISFIRE"}))]
    with (
        scripted(CannonDriver, script, **KW) as (c, _),
        pytest.raises(DeviceError, match="MISFIRE after FIRE"),
    ):
        c.fire()


def test_fired_without_shot_number_is_garbled() -> None:
    script = [armed_status(), (cmd(2, "FIRE"), ok(2) + event("FIRED", {"SHOT": "x"}))]
    with scripted(CannonDriver, script, **KW) as (c, _), pytest.raises(GarbledReply, match="FIRED event"):
        c.fire()


def test_device_still_refuses_fire_if_an_interlock_opened_meanwhile() -> None:
    script = [armed_status(), (cmd(2, "FIRE"), err(2, "ILK", "door open") + event("ILK", {"DOOR": 0}))]
    with scripted(CannonDriver, script, **KW) as (c, _), pytest.raises(DeviceRefused) as info:
        c.fire()
    assert (info.value.command, info.value.code) == ("FIRE", "ILK")
    assert c.transport.all_events.get_nowait().event.name == "ILK"


def test_device_refusing_arm_for_pressure() -> None:
    script = [(cmd(1, "STATUS"), ok(1, cannon_status())), (cmd(2, "ARM"), err(2, "PRESSURE"))]
    with scripted(CannonDriver, script, **KW) as (c, _), pytest.raises(DeviceRefused, match="PRESSURE"):
        c.arm()


@pytest.mark.parametrize(
    ("fields", "why"),
    [
        ({k: v for k, v in cannon_status().items() if k != "P"}, "lacks field P"),
        ({**cannon_status(), "STATE": "LIMBO"}, "LIMBO"),
        ({**cannon_status(), "DOOR": 2}, "expected 0 or 1"),
        ({**cannon_status(), "SHOTS": "many"}, "many"),
    ],
)
def test_bad_status_is_garbled_naming_the_field(fields: dict, why: str) -> None:
    with (
        scripted(CannonDriver, [(cmd(1, "STATUS"), ok(1, fields))], **KW) as (c, _),
        pytest.raises(GarbledReply, match=f"STATUS reply.*{why}"),
    ):
        c.status()


def test_bad_environment_is_garbled() -> None:
    with (
        scripted(CannonDriver, [(cmd(1, "ENV"), ok(1, {"TEMP_C": 21.0}))], **KW) as (c, _),
        pytest.raises(GarbledReply, match="RH"),
    ):
        c.environment()
