"""serve(): the devices of one world on TCP ports (and ptys), stopped by an Event, bounded."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import pytest
import serial

from rig.drivers.gates.codec import parse_crossing
from rig.physics import DEFAULT_PARAMS, PivotedBat, predict_bat
from rig.simulators.scene import Scene
from rig.simulators.serve import serve
from rig.simulators.warmup import warm_up
from tests.load import stop_group
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


def test_warm_up_fires_the_scenes_own_physics() -> None:
    """The dummy shot reaches the bat and gives the model's e_A for the scene's bat (ideal scene)."""
    scene = Scene.load("ideal")
    shot = warm_up(scene)
    assert shot.hit and shot.impact_speed == pytest.approx(60.8, rel=0.01)
    expected = predict_bat(
        DEFAULT_PARAMS,
        shot.impact_speed,
        None,
        PivotedBat(moi_kgm2=scene.bat.moi_kgm2, impact_from_pivot_m=shot.impact_from_pivot_m),
    )
    assert shot.e_a == pytest.approx(expected.e_a, rel=1e-9)


def test_warm_up_leaves_faults_out_so_the_dummy_shot_reaches_the_bat() -> None:
    scene = Scene.model_validate({"effects": [{"kind": "misfire", "shots": [1]}]})
    assert warm_up(scene).hit


MISFIRE_2 = Scene.model_validate({"effects": [{"kind": "misfire", "shots": [2]}]})


@pytest.mark.parametrize("served", [(MISFIRE_2, "tcp")], indirect=True)
def test_the_served_world_starts_fresh_after_the_warm_up(served: tuple[dict[str, str], Lines]) -> None:
    """The warm-up's shot is not the served world's: its first FIRE is shot 1, the fault hits shot 2."""
    urls, _ = served
    gates, _ = shot(urls)
    cannon = Port(urls["cannon"], "cannon", timeout=WAIT_S)
    assert cannon.ask("STATUS").named()["SHOTS"] == "1"
    gates.ask("ARM")
    cannon.ask("PSET", 395.0)
    cannon.wait_event("READY")
    cannon.ask("ARM")
    cannon.ask("FIRE")
    assert cannon.wait_event("FAULT").named()["CODE"] == "MISFIRE"


def _serve_process(*extra: str) -> tuple[subprocess.Popen[str], dict[str, str]]:
    """`rig sim serve --kind tcp ...` in its own session; its printed URLs."""
    server = subprocess.Popen(
        [sys.executable, "-m", "rig.cli", "sim", "serve", "--kind", "tcp", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    assert server.stdout is not None
    urls = {}
    for _ in range(3):  # a fresh checkout compiles the kernel first: no deadline but the test's
        line = server.stdout.readline()
        if not line:
            break
        name, url = line.split()
        urls[name] = url
    return server, urls


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX process groups")
@pytest.mark.usefixtures("cpu_load")
def test_rig_sim_serve_answers_the_first_fire_within_the_device_promise() -> None:
    """Devices answer every command within 100 ms (docs/devices/README.md), the first FIRE too.

    Before the warm-up the first FIRE loaded the collision kernel inside its reply: ~0.4 s idle,
    1.4 s on a loaded machine, past the controller's 1 s reply timeout (the shot was lost).
    """
    server, urls = _serve_process("--scene", "lab")
    try:
        assert set(urls) == {"cannon", "gates", "clamp"}, server.stderr.read() if server.poll() else urls
        cannon, gates, clamp = (Port(urls[d], d, timeout=WAIT_S) for d in ("cannon", "gates", "clamp"))
        clamp.ask("CLAMP")
        clamp.wait_event("LOCK")
        gates.ask("ARM")
        cannon.ask("PSET", 395.0)
        cannon.wait_event("READY")
        cannon.ask("ARM")
        t0 = time.perf_counter()
        cannon.ask("FIRE")
        first_fire_s = time.perf_counter() - t0
        assert [parse_crossing(gates.wait_event("G")).gate for _ in range(6)] == [1, 2, 3, 3, 2, 1]
        assert first_fire_s < 0.1
    finally:
        stop_group(server)


def test_warm_up_loads_the_compiled_kernel() -> None:
    """A served rig must not switch from the interpreted kernel to numba inside a FIRE reply (a shot
    was lost to that under load): after the warm-up, single solves run compiled."""
    code = (
        "import sys\n"
        "from rig.simulators.scene import Scene\n"
        "from rig.simulators.warmup import warm_up\n"
        "from rig.physics import fast\n"
        "warm_up(Scene.load('lab'))\n"
        "print('rig.physics._dop853' in sys.modules, fast._single().__name__)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    assert out.stdout.split() == ["True", "rig.physics._dop853"]
