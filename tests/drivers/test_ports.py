"""Real pyserial ports through the transport: bad URLs, loop://, spy:// on a pty, socket://, and a
scheme registered from outside (as simulators register sim://)."""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

from rig.core.errors import DeviceGone, GarbledReply
from rig.drivers.codec import CheckedCommand, DeviceCodec
from rig.drivers.gates.codec import SPECS
from rig.drivers.gates.driver import GatesDriver
from rig.drivers.transport import LineTransport, open_port
from rig.drivers.wire import Event, encode


@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("/dev/ttyNOPE_42", "No such file"),
        ("nope://somewhere", "protocol 'nope' not known"),
        ("socket://127.0.0.1:1", "refused"),
        ("socket://no-port-given", "socket://"),
        ("spy:///dev/ttyNOPE_42", "No such file"),
    ],
)
def test_unopenable_port_is_device_gone_naming_device_and_url(url: str, why: str) -> None:
    with pytest.raises(DeviceGone, match=why) as info:
        open_port(url, device="gates")
    assert info.value.device == "gates" and repr(url) in str(info.value)
    with pytest.raises(DeviceGone, match="gates: cannot open"):
        LineTransport("gates", url, SPECS)


def test_loop_url_works_through_the_transport() -> None:
    port = open_port("loop://", timeout=0.02)
    port.write(encode(Event("G", ("N=1", "T=99"))))  # already waiting when the transport starts
    with LineTransport("gates", port, SPECS, reply_timeout_s=0.2) as t:
        assert t.wait_event("G", 1.0).named()["T"] == "99"
        with pytest.raises(GarbledReply, match="neither OK nor ERR"):
            t.request("CLOCK")  # a loopback hands the host its own command
        assert t.traffic.data("rx").endswith(t.traffic.data("tx"))
        t.reconnect()  # the same port object, closed and opened again
        assert t.gone is None


def test_a_scheme_registered_elsewhere_reaches_the_transport(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(
        serial, "protocol_handler_packages", [*serial.protocol_handler_packages, "tests.drivers.handlers"]
    )
    with GatesDriver("testloop://", reply_timeout_s=0.2) as gates:
        assert gates.transport.url == "testloop://"
        with pytest.raises(GarbledReply):
            gates.clock()
        gates.reconnect()  # by URL: a new port object
        with pytest.raises(GarbledReply):
            gates.clock()


class Responder:
    """A device on a file descriptor or socket: answers every command OK with T=<seq>."""

    def __init__(self, read, write, drop_on: str | None = None) -> None:
        self.read, self.write = read, write
        self.codec = DeviceCodec(SPECS)
        self.stop = threading.Event()
        # close the connection instead of answering this verb; set before the thread starts
        self.drop_on = drop_on
        self.thread = threading.Thread(target=self.run, daemon=True)

    def start(self) -> Responder:
        """Answer from now on (a fixture publishes the responder first: it may answer at once)."""
        self.thread.start()
        return self

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                data = self.read()
            except OSError:
                return
            if data is None:
                continue
            if data == b"":
                return
            for item in self.codec.feed(data):
                if isinstance(item, CheckedCommand):
                    if item.verb == self.drop_on:
                        self.drop_on = None
                        return
                    self.write(DeviceCodec.ok(item.seq, {"T": item.seq}))


@pytest.fixture
def pty_device() -> Iterator[tuple[str, list[int]]]:
    master, slave = os.openpty()
    path = os.ttyname(slave)

    def read() -> bytes | None:
        ready, _, _ = select.select([fds[0]], [], [], 0.02)
        return os.read(fds[0], 256) if ready else None

    fds = [master]
    device = Responder(read, lambda b: os.write(fds[0], b)).start()
    yield path, fds
    device.stop.set()
    device.thread.join(1)
    for fd in (fds[0], slave):
        with contextlib.suppress(OSError):
            os.close(fd)


def test_spy_wraps_a_real_tty_and_logs_the_wire(pty_device, tmp_path: Path) -> None:
    path, _ = pty_device
    log = tmp_path / "wire.txt"
    with GatesDriver(f"spy://{path}?file={log}", reply_timeout_s=1.0) as gates:
        assert gates.clock() == 1
        assert gates.clock() == 2
    text = log.read_text()
    assert "TX" in text and "RX" in text and "CLOCK" in text


def test_tty_master_closing_is_device_gone(pty_device) -> None:
    path, fds = pty_device
    with GatesDriver(path, reply_timeout_s=1.0) as gates:
        assert gates.clock() == 1
        os.close(fds[0])
        deadline = time.monotonic() + 2
        while gates.transport.gone is None and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(DeviceGone, match="read failed"):
            gates.disarm()


class TcpDevice:
    """A device behind socket://, one connection at a time, that can hang up."""

    def __init__(self) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.server.settimeout(0.05)
        self.url = f"socket://127.0.0.1:{self.server.getsockname()[1]}"
        self.stop = threading.Event()
        self.connections = 0
        self.current: Responder | None = None
        self.drop_on: str | None = None
        threading.Thread(target=self.serve, daemon=True).start()

    def serve(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self.connections += 1
            conn.settimeout(0.05)

            def read(conn: socket.socket = conn) -> bytes | None:
                try:
                    return conn.recv(256)
                except TimeoutError:
                    return None

            responder = Responder(read, conn.sendall, drop_on=self.drop_on)
            self.drop_on = None
            # published before it answers: a client holding its first reply may hang_up() at once
            self.current = responder
            responder.start()
            responder.thread.join()
            conn.close()

    def hang_up(self) -> None:
        assert self.current is not None
        self.current.stop.set()

    def close(self) -> None:
        self.stop.set()
        if self.current:
            self.current.stop.set()
        self.server.close()


@pytest.fixture
def tcp_device() -> Iterator[TcpDevice]:
    device = TcpDevice()
    yield device
    device.close()


def test_socket_hang_up_is_gone_until_reconnect(tcp_device: TcpDevice) -> None:
    with GatesDriver(tcp_device.url, reply_timeout_s=1.0) as gates:
        assert gates.clock() == 1
        tcp_device.hang_up()
        deadline = time.monotonic() + 2
        while gates.transport.gone is None and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(DeviceGone, match="check its cable and power"):
            gates.arm()
        gates.reconnect()
        gates.arm()
    assert tcp_device.connections == 2


def test_socket_query_lost_midway_reconnects_and_retries(tcp_device: TcpDevice) -> None:
    tcp_device.drop_on = "CLOCK"
    with GatesDriver(tcp_device.url, reply_timeout_s=1.0) as gates:
        assert gates.clock() == 2  # seq 1 was lost with the first connection
    assert tcp_device.connections == 2
