"""Gates driver specifics: streamed crossings with host receive times, self-test, parse errors."""

from __future__ import annotations

import time

import pytest

from rig.core.devices import GateCrossing
from rig.core.errors import DeviceError, DeviceGone, GarbledReply
from rig.drivers.gates.driver import GatesDriver
from tests.drivers.fakeport import cmd, event, ok, scripted


def g(gate: int, tick: int) -> bytes:
    return event("G", {"N": gate, "T": tick})


def test_crossings_stream_as_they_arrive_with_host_receive_times() -> None:
    with scripted(GatesDriver, [(cmd(1, "ARM"), ok(1))]) as (gates, port):
        gates.arm()
        start = time.monotonic()
        port.inject(g(1, 1000), delay_s=0.02)
        port.inject(g(2, 51000), delay_s=0.07)
        port.inject(g(3, 101000), delay_s=0.12)
        seen: list[tuple[GateCrossing, float]] = []
        for crossing in gates.crossings(timeout_s=0.2):
            seen.append((crossing, time.monotonic()))
        end = time.monotonic()
    crossings = [c for c, _ in seen]
    assert [(c.gate, c.tick) for c in crossings] == [(1, 1000), (2, 51000), (3, 101000)]
    hosts = [c.host_time_s for c in crossings]
    assert start < hosts[0] < hosts[1] < hosts[2] < end
    assert hosts[1] - hosts[0] == pytest.approx(0.05, abs=0.03)
    assert seen[0][1] < hosts[1]  # the first was handed out before the second arrived
    assert end - hosts[2] >= 0.2  # the stream ends after `timeout_s` of silence
    rx_times = {r.t_s for r in gates.transport.traffic.records() if r.direction == "rx"}
    assert set(hosts) <= rx_times  # stamped when read, as in the raw log


def test_crossings_in_one_read_share_a_receive_time() -> None:
    with scripted(GatesDriver, []) as (gates, port):
        port.inject(g(1, 5) + g(2, 9))
        first, second = gates.crossings(timeout_s=0.05)
    assert first.host_time_s == second.host_time_s and (first.tick, second.tick) == (5, 9)


def test_no_crossing_ends_the_stream_empty() -> None:
    with scripted(GatesDriver, []) as (gates, _):
        start = time.monotonic()
        assert list(gates.crossings(timeout_s=0.05)) == []
        assert time.monotonic() - start < 0.2


def test_arm_forgets_crossings_from_before() -> None:
    with scripted(GatesDriver, [(cmd(1, "ARM"), ok(1) + g(3, 77))]) as (gates, port):
        port.inject(g(1, 1))
        time.sleep(0.03)
        gates.arm()
        assert [c.tick for c in gates.crossings(timeout_s=0.05)] == [77]


@pytest.mark.parametrize(
    ("frame", "why"),
    [
        (event("G", {"N": 1}), "malformed gate event"),
        (event("G", {"N": "one", "T": 5}), "malformed gate event"),
        (g(4, 5), "gate event out of range: gate 4"),
        (g(0, 5), "gate event out of range: gate 0"),
        (g(1, -5), "gate event out of range: gate 1, tick -5"),
    ],
)
def test_malformed_crossing_is_garbled(frame: bytes, why: str) -> None:
    with scripted(GatesDriver, []) as (gates, port):
        port.inject(frame)
        with pytest.raises(GarbledReply, match=f"G event: {why}"):
            list(gates.crossings(timeout_s=0.1))


def test_gate_count_from_config_bounds_the_gate_number() -> None:
    script = [(cmd(1, "CFG"), ok(1, {"N": 4, "TICK_NS": 100.0, "BITS": 32}))]
    with scripted(GatesDriver, script) as (gates, port):
        gates.config()
        port.inject(g(4, 5))
        assert [c.gate for c in gates.crossings(timeout_s=0.05)] == [4]


def test_port_vanishing_mid_stream_raises_device_gone() -> None:
    with scripted(GatesDriver, []) as (gates, port):
        port.inject(g(1, 5))
        stream = gates.crossings(timeout_s=1.0)
        assert next(stream).gate == 1
        port.vanish()
        with pytest.raises(DeviceGone):
            next(stream)


def test_self_test_failure_names_the_gate() -> None:
    script = [(cmd(1, "TEST"), ok(1, {"RESULT": "FAIL", "GATE": 2}))]
    with scripted(GatesDriver, script) as (gates, _), pytest.raises(DeviceError, match="gate 2") as info:
        gates.self_test()
    assert type(info.value) is DeviceError and info.value.device == "gates"


@pytest.mark.parametrize("fields", [{"RESULT": "MAYBE"}, {}])
def test_self_test_with_no_verdict_is_garbled(fields: dict) -> None:
    with (
        scripted(GatesDriver, [(cmd(1, "TEST"), ok(1, fields))]) as (gates, _),
        pytest.raises(GarbledReply, match="neither PASS nor FAIL"),
    ):
        gates.self_test()


@pytest.mark.parametrize(
    ("fields", "why"),
    [
        ({"N": 3, "TICK_NS": 100.0}, "lacks field BITS"),
        ({"N": 3, "TICK_NS": 100.0, "BITS": 4}, "implausible"),
    ],
)
def test_bad_config_is_garbled(fields: dict, why: str) -> None:
    with (
        scripted(GatesDriver, [(cmd(1, "CFG"), ok(1, fields))]) as (gates, _),
        pytest.raises(GarbledReply, match=why),
    ):
        gates.config()


def test_clock_without_a_value_is_garbled() -> None:
    with (
        scripted(GatesDriver, [(cmd(1, "CLOCK"), ok(1))]) as (gates, _),
        pytest.raises(GarbledReply, match="CLOCK reply: lacks field T"),
    ):
        gates.clock()
