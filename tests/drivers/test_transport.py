"""LineTransport against a scripted port: matching, stale replies, events, loss and reconnect."""

from __future__ import annotations

import threading
import time

import pytest

from rig.core.errors import (
    DeviceGone,
    DeviceRefused,
    DeviceTimeout,
    GarbledReply,
    ParameterError,
)
from rig.drivers.codec import DeviceCodec
from rig.drivers.gates.codec import SPECS
from rig.drivers.transport import LineTransport
from rig.drivers.wire import Event, Reply
from tests.drivers.fakeport import SILENT, VANISH, WRITE_FAILS, FakePort, cmd, corrupt, err, event, ok

T = 0.1  # reply timeout for these tests


def transport(port: FakePort, **kw) -> LineTransport:
    kw.setdefault("reply_timeout_s", T)
    return LineTransport("gates", port, SPECS, **kw)


def test_reply_resolves_the_request_and_traffic_is_logged_in_order() -> None:
    seen = []
    port = FakePort([(cmd(1, "CLOCK"), ok(1, {"T": 99}))])
    with transport(port, on_traffic=seen.append) as t:
        assert t.request("CLOCK") == Reply(1, ("T=99",))
    port.assert_done()
    records = t.traffic.records()
    assert [r.direction for r in records][:1] == ["tx"]
    assert t.traffic.data("tx") == cmd(1, "CLOCK") and t.traffic.data("rx") == ok(1, {"T": 99})
    assert [r.t_s for r in records] == sorted(r.t_s for r in records)
    assert seen == records  # the hook saw every record


def test_replies_split_into_single_bytes_are_reassembled() -> None:
    port = FakePort([(cmd(1, "CFG"), ok(1, {"N": 3, "TICK_NS": 100.0, "BITS": 32}))], chunk=1)
    with transport(port) as t:
        assert t.request("CFG").named() == {"N": "3", "TICK_NS": "100.0", "BITS": "32"}
    assert len(t.traffic.records()) > 10  # one rx record per byte read


def test_error_reply_raises_refused_with_the_code() -> None:
    port = FakePort([(cmd(1, "ARM"), err(1, "STATE", "already armed"))])
    with transport(port) as t, pytest.raises(DeviceRefused) as info:
        t.request("ARM")
    assert (info.value.command, info.value.code, info.value.text) == ("ARM", "STATE", "already armed")
    assert info.value.device == "gates"


def test_garbled_reply_fails_the_request_naming_the_reason() -> None:
    with transport(FakePort([(cmd(1, "CLOCK"), corrupt(ok(1, {"T": 5})))])) as t:
        with pytest.raises(GarbledReply, match="CRC mismatch"):
            t.request("CLOCK")
        assert len(t.garbled()) == 1


def test_garbage_with_no_request_waiting_is_recorded_not_raised() -> None:
    port = FakePort([(cmd(1, "CLOCK"), ok(1, {"T": 5}))])
    with transport(port) as t:
        port.inject(b"\x00\xffnoise\r\n")
        time.sleep(0.05)
        assert t.request("CLOCK").named()["T"] == "5"
        assert [g.reason for _, g in t.garbled()] == ["no *CRC trailer"]


def test_no_reply_times_out_within_the_deadline() -> None:
    with transport(FakePort([(cmd(1, "CLOCK"), SILENT)])) as t:
        start = time.monotonic()
        with pytest.raises(DeviceTimeout, match="no reply to CLOCK"):
            t.request("CLOCK")
        assert T <= time.monotonic() - start < T + 0.15


def test_a_late_reply_is_stale_and_dropped() -> None:
    port = FakePort([(cmd(1, "CLOCK"), SILENT), (cmd(2, "CLOCK"), ok(1, {"T": 1}) + ok(2, {"T": 2}))])
    with transport(port) as t:
        with pytest.raises(DeviceTimeout):
            t.request("CLOCK")
        assert t.request("CLOCK").named()["T"] == "2"
        assert [r for _, r in t.stale()] == [Reply(1, ("T=1",))]
    port.assert_done()


def test_an_unrequested_reply_between_requests_is_stale() -> None:
    port = FakePort([(cmd(1, "CLOCK"), ok(1, {"T": 1}))])
    with transport(port) as t:
        port.inject(ok(42))
        time.sleep(0.03)
        assert t.request("CLOCK").named()["T"] == "1"
        assert [r.seq for _, r in t.stale()] == [42]


def test_events_before_and_after_the_reply_are_kept_in_order() -> None:
    port = FakePort([(cmd(1, "ARM"), event("G", {"N": 1, "T": 10}) + ok(1) + event("G", {"N": 2, "T": 20}))])
    with transport(port) as t:
        t.request("ARM")
        first, second = t.next_event("G", T), t.next_event("G", T)
        assert first.event == Event("G", ("N=1", "T=10")) and second.event.named()["N"] == "2"
        assert first.index < second.index
        assert t.all_events.get_nowait() == first and t.all_events.get_nowait() == second


def test_event_arriving_after_the_reply_is_waited_for() -> None:
    port = FakePort([(cmd(1, "ARM"), ok(1))])
    with transport(port) as t:
        t.request("ARM")
        port.inject(event("G", {"N": 3, "T": 30}), delay_s=0.03)
        assert t.wait_event("G", 1.0).named()["T"] == "30"


def test_waiting_for_several_names_takes_the_oldest() -> None:
    port = FakePort()
    with transport(port) as t:
        port.inject(event("B") + event("A") + event("B", {"K": 2}))
        assert t.wait_event(("A", "B"), T) == Event("B")
        assert t.wait_event(("A", "B"), T) == Event("A")
        assert t.wait_event("B", T, lambda e: e.named().get("K") == "2").named()["K"] == "2"


def test_predicate_discards_events_that_fail_it() -> None:
    port = FakePort()
    with transport(port) as t:
        port.inject(event("LOCK", {"L": 0}) + event("LOCK", {"L": 1}))
        assert t.wait_event("LOCK", T, lambda e: e.named()["L"] == "1").named()["L"] == "1"
        with pytest.raises(DeviceTimeout, match="no LOCK event"):
            t.wait_event("LOCK", 0.02)


def test_clear_events_forgets_kept_events_but_not_the_log() -> None:
    port = FakePort()
    with transport(port) as t:
        port.inject(event("G", {"N": 1, "T": 1}))
        t.wait_event("G", T)
        port.inject(event("G", {"N": 2, "T": 2}))
        time.sleep(0.03)
        assert t.clear_events("G") == 1
        with pytest.raises(DeviceTimeout):
            t.wait_event("G", 0.02)
        assert t.traffic.data("rx").count(b"! G") == 2


def test_bad_arguments_raise_parameter_error_and_send_nothing() -> None:
    port = FakePort()
    with transport(port) as t:
        with pytest.raises(ParameterError, match="takes 0 argument"):
            t.request("CLOCK", 5)
        with pytest.raises(ParameterError, match="unknown command"):
            t.request("FIRE")
    assert port.written == b""


def test_requests_from_two_threads_are_serialised() -> None:
    class AutoPort(FakePort):
        """Answers every command OK, with its verb."""

        def _match(self) -> None:
            for c in DeviceCodec(SPECS).feed(bytes(self._unmatched)):
                self._rx += ok(c.seq, {"V": c.verb})
            self._unmatched.clear()
            self._cv.notify_all()

    results: list[str] = []
    with transport(AutoPort()) as t:
        threads = [
            threading.Thread(target=lambda v=v: results.append(t.request(v).named()["V"]))
            for v in ("CLOCK", "CFG", "ID", "TEST") * 5
        ]
        for th in threads:
            th.start()
        for th in threads:
            th.join(2)
    assert sorted(results) == sorted(["CLOCK", "CFG", "ID", "TEST"] * 5)


# -- loss and reconnect ------------------------------------------------------------------------


def test_write_failure_is_device_gone_and_sticks_until_reconnect() -> None:
    port = FakePort([(cmd(1, "ARM"), WRITE_FAILS), (cmd(2, "ARM"), ok(2))])
    with transport(port) as t:
        with pytest.raises(DeviceGone, match="write failed"):
            t.request("ARM")
        assert port.opens == 0  # a command with effects is never retried by itself
        with pytest.raises(DeviceGone, match="check its cable and power"):
            t.request("ARM")
        with pytest.raises(DeviceGone):
            t.wait_event("G", 1.0)
        t.reconnect()
        assert t.gone is None
        t.request("ARM")
    port.assert_done()


def test_query_lost_midway_is_retried_once_after_reconnect() -> None:
    port = FakePort([(cmd(1, "CLOCK"), VANISH), (cmd(2, "CLOCK"), ok(2, {"T": 7}))])
    with transport(port) as t:
        assert t.request("CLOCK").named()["T"] == "7"
    assert port.opens == 1
    port.assert_done()


def test_query_retry_happens_only_once() -> None:
    port = FakePort([(cmd(1, "CLOCK"), VANISH), (cmd(2, "CLOCK"), VANISH)])
    with transport(port) as t, pytest.raises(DeviceGone):
        t.request("CLOCK")
    assert port.opens == 1


def test_command_with_effects_lost_midway_is_not_retried() -> None:
    port = FakePort([(cmd(1, "DISARM"), VANISH)])
    with transport(port) as t:
        start = time.monotonic()
        with pytest.raises(DeviceGone, match="DISARM"):
            t.request("DISARM", timeout_s=5.0)
        assert time.monotonic() - start < 1.0  # noticed at once, not at the deadline
    assert port.opens == 0
    port.assert_done()


def test_failed_reconnect_stays_gone() -> None:
    port = FakePort([(cmd(1, "CLOCK"), VANISH), (cmd(2, "CLOCK"), ok(2, {"T": 1}))])
    port.open_error = OSError(2, "No such file or directory")
    with transport(port) as t:
        with pytest.raises(DeviceGone, match="No such file"):
            t.request("CLOCK")
        with pytest.raises(DeviceGone, match="reconnect failed"):
            t.request("CLOCK")
        port.open_error = None
        t.reconnect()
        assert t.request("CLOCK").named()["T"] == "1"


def test_port_vanishing_while_idle_wakes_event_waiters() -> None:
    port = FakePort()
    with transport(port) as t:
        threading.Timer(0.03, port.vanish).start()
        start = time.monotonic()
        with pytest.raises(DeviceGone, match="read failed"):
            t.wait_event("G", 5.0)
        assert time.monotonic() - start < 1.0
        with pytest.raises(DeviceGone):
            t.request("CLOCK")  # gone before the call: no automatic reconnect
    assert port.opens == 0


def test_events_kept_before_the_loss_are_still_handed_out() -> None:
    port = FakePort()
    with transport(port) as t:
        port.inject(event("G", {"N": 1, "T": 1}))
        time.sleep(0.03)
        port.vanish()
        time.sleep(0.03)
        assert t.wait_event("G", T).named()["N"] == "1"
        with pytest.raises(DeviceGone):
            t.wait_event("G", T)


def test_half_a_line_does_not_survive_a_reconnect() -> None:
    port = FakePort([(cmd(1, "CLOCK"), ok(2)[:4] + b""), (cmd(2, "CLOCK"), ok(2, {"T": 3}))])
    with transport(port) as t:
        with pytest.raises(DeviceTimeout):
            t.request("CLOCK")
        t.reconnect()
        assert t.request("CLOCK").named()["T"] == "3"
        assert t.garbled() == []


def test_reader_thread_death_is_device_gone() -> None:
    class BrokenPort(FakePort):
        def read(self, size: int = 1) -> bytes:
            raise RuntimeError("driver bug")

    with transport(BrokenPort()) as t:
        time.sleep(0.02)
        with pytest.raises(DeviceGone, match="reader thread died"):
            t.request("CLOCK")


def test_close_stops_the_thread_and_later_calls_are_gone() -> None:
    port = FakePort()
    t = transport(port)
    conn = t._conn
    assert conn.reading
    t.close()
    t.close()  # idempotent
    assert not conn.reading
    assert not port.is_open
    with pytest.raises(DeviceGone, match="closed"):
        t.request("CLOCK")
    with pytest.raises(DeviceGone, match="closed"):
        t.reconnect()


def test_close_during_a_request_ends_it_at_once() -> None:
    port = FakePort([(cmd(1, "CLOCK"), SILENT)])
    t = transport(port)
    threading.Timer(0.03, t.close).start()
    start = time.monotonic()
    with pytest.raises(DeviceGone, match="closed"):
        t.request("CLOCK", timeout_s=5.0)
    assert time.monotonic() - start < 1.0
