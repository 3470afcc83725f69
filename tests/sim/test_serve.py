"""serve(): the devices of one world on TCP ports (and ptys), stopped by an Event, bounded."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterator

import pytest
import serial

from drivers.gates.codec import parse_crossing
from simulators.scene import Scene
from simulators.serve import serve
from tests.sim.hosts import Port

WAIT_S = 5.0


class Lines:
    """A thread-safe stdout stand-in that collects `<name> <url>` lines."""

    def __init__(self) -> None:
        self.text = ""
        self.cond = threading.Condition()

    def write(self, s: str) -> int:
        with self.cond:
            self.text += s
            self.cond.notify_all()
        return len(s)

    def flush(self) -> None:
        pass

    def wait(self, n: int) -> list[tuple[str, str]]:
        with self.cond:
            assert self.cond.wait_for(lambda: self.text.count("\n") >= n, WAIT_S), self.text
            return [tuple(line.split(" ", 1)) for line in self.text.splitlines()]  # type: ignore[misc]


@pytest.fixture
def served(request: pytest.FixtureRequest) -> Iterator[tuple[dict[str, str], Lines]]:
    scene, kind = request.param
    out, stop = Lines(), threading.Event()
    thread = threading.Thread(target=serve, args=(scene,), kwargs={"kind": kind, "stop": stop, "out": out})
    thread.start()
    try:
        yield dict(out.wait(3)), out
    finally:
        stop.set()
        thread.join(WAIT_S)
    assert not thread.is_alive(), "serve() did not stop"


def shot(urls: dict[str, str]) -> tuple[Port, list[int]]:
    cannon, gates, clamp = (Port(urls[d], d, timeout=WAIT_S) for d in ("cannon", "gates", "clamp"))
    clamp.ask("CLAMP")
    clamp.wait_event("LOCK")
    gates.ask("ARM")
    cannon.ask("PSET", 395.0)
    cannon.wait_event("READY")
    cannon.ask("ARM")
    cannon.ask("FIRE")
    return gates, [parse_crossing(gates.wait_event("G")).gate for _ in range(2)]


@pytest.mark.parametrize("served", [("ideal", "tcp")], indirect=True)
def test_tcp_serves_a_whole_shot_then_closes(served: tuple[dict[str, str], Lines]) -> None:
    urls, _ = served
    assert sorted(urls) == ["cannon", "clamp", "gates"]
    assert all(u.startswith("socket://127.0.0.1:") for u in urls.values())
    gates, first = shot(urls)
    rest = [parse_crossing(gates.wait_event("G")).gate for _ in range(4)]
    assert first + rest == [1, 2, 3, 3, 2, 1]


def test_tcp_ports_are_released_after_stop() -> None:
    out, stop = Lines(), threading.Event()
    thread = threading.Thread(target=serve, args=("ideal",), kwargs={"kind": "tcp", "stop": stop, "out": out})
    thread.start()
    urls = dict(out.wait(3))
    stop.set()
    thread.join(WAIT_S)
    assert not thread.is_alive()
    host, port = urls["cannon"].removeprefix("socket://").split(":")
    with pytest.raises(OSError), socket.create_connection((host, int(port)), timeout=1.0):
        pass


UNPLUG = Scene.model_validate({"effects": [{"kind": "unplug", "shots": [1], "device": "gates", "after": 2}]})


@pytest.mark.parametrize("served", [(UNPLUG, "tcp")], indirect=True)
def test_tcp_unplug_drops_the_connection_and_a_new_one_replugs(served: tuple[dict[str, str], Lines]) -> None:
    urls, _ = served
    gates, first = shot(urls)
    assert first == [1, 2]
    with pytest.raises(serial.SerialException):
        gates.port.read(1)
    gates.port.close()
    again = Port(urls["gates"], "gates", timeout=WAIT_S)
    assert again.ask("ID").named()["MODEL"] == "SIM-GATES"


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="no ptys on this platform")
@pytest.mark.parametrize("served", [("ideal", "pty")], indirect=True)
def test_pty_serves_each_device_on_its_own_terminal(served: tuple[dict[str, str], Lines]) -> None:
    urls, _ = served
    assert all(u.startswith("/dev/") for u in urls.values())
    cannon = Port(urls["cannon"], "cannon", timeout=WAIT_S)
    assert cannon.ask("ID").named()["MODEL"] == "SIM-CANNON"
