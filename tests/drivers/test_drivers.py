"""Every driver method against scripted exchanges: success and each way the device can fail."""

from __future__ import annotations

import time

import pytest

from rig.core.devices import Cannon, Clamp, Gates
from rig.core.errors import DeviceGone, DeviceRefused, DeviceTimeout, GarbledReply
from rig.drivers.cannon.driver import CannonDriver
from rig.drivers.clamp.driver import ClampDriver
from rig.drivers.gates.driver import GatesDriver
from rig.drivers.transport import SAFE_TO_REPEAT
from tests.drivers.cases import CASES, FAST, Case
from tests.drivers.fakeport import SILENT, WRITE_FAILS, FakePort, corrupt, err, ok, scripted, shift

ids = [c.name for c in CASES]


def with_first_answer(case: Case, answer: bytes | object) -> list:
    return [(case.script[0][0], answer)]


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_success(case: Case) -> None:
    with scripted(case.driver, case.script, **FAST[case.driver]) as (driver, _):
        result = case.call(driver)
    assert result == case.result


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_error_reply_is_refused_with_its_code(case: Case) -> None:
    script = with_first_answer(case, err(1, "BUSY", "stage moving"))
    with (
        scripted(case.driver, script, **FAST[case.driver]) as (driver, _),
        pytest.raises(DeviceRefused) as info,
    ):
        case.call(driver)
    assert (info.value.command, info.value.code, info.value.text) == (case.first_verb, "BUSY", "stage moving")
    assert str(info.value).startswith(driver.name + ": refused")


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_garbled_reply_names_the_reason(case: Case) -> None:
    script = with_first_answer(case, corrupt(ok(1)))
    expected = f"garbled reply to {case.first_verb}: CRC mismatch"
    with (
        scripted(case.driver, script, **FAST[case.driver]) as (driver, _),
        pytest.raises(GarbledReply, match=expected),
    ):
        case.call(driver)


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_no_reply_times_out_within_the_deadline(case: Case) -> None:
    """The 0.1 s reply deadline is waited out once: not cut short, and the command not sent again
    (the scripted port refuses a second write). The upper bound leaves a busy machine's scheduling
    1.5 s: a wait repeated or a deadline of seconds still fails it, a late thread does not."""
    with scripted(case.driver, with_first_answer(case, SILENT), **FAST[case.driver]) as (driver, _):
        start = time.monotonic()
        with pytest.raises(DeviceTimeout, match=f"no reply to {case.first_verb}"):
            case.call(driver)
        assert 0.1 <= time.monotonic() - start < 0.1 + 1.5


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_port_failing_is_device_gone_and_only_queries_try_to_reconnect(case: Case) -> None:
    port = FakePort(with_first_answer(case, WRITE_FAILS))
    port.open_error = OSError(2, "No such file or directory: '/dev/ttyUSB0'")
    with case.driver(port, reply_timeout_s=0.1, **FAST[case.driver]) as driver:
        with pytest.raises(DeviceGone):
            case.call(driver)
        with pytest.raises(DeviceGone):
            case.call(driver)  # and again, without touching the port
    assert port.opens == (1 if case.first_verb in SAFE_TO_REPEAT else 0)
    port.assert_done()


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_reconnect_after_loss_restores_the_method(case: Case) -> None:
    port = FakePort(with_first_answer(case, WRITE_FAILS) + shift(case.script, 1))
    port.open_error = OSError(19, "No such device")
    with case.driver(port, reply_timeout_s=0.1, **FAST[case.driver]) as driver:
        with pytest.raises(DeviceGone):
            case.call(driver)
        port.open_error = None
        driver.reconnect()
        assert case.call(driver) == case.result
    port.assert_done()


def test_drivers_implement_the_core_interfaces() -> None:
    for cls, interface in ((CannonDriver, Cannon), (GatesDriver, Gates), (ClampDriver, Clamp)):
        with cls(FakePort()) as driver:
            assert isinstance(driver, interface)


def test_drivers_open_urls_and_name_the_device_when_they_cannot() -> None:
    with pytest.raises(DeviceGone, match=r"clamp: cannot open '/dev/ttyNOPE_0'"):
        ClampDriver("/dev/ttyNOPE_0")
    with GatesDriver("loop://") as gates:
        assert gates.transport.url == "loop://"
