"""The sim:// pyserial URL handler: shared worlds, timeouts, unplug, and a shot through ports."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
import serial

from rig.core.errors import ConfigError
from rig.drivers.codec import HostCodec
from rig.drivers.gates.codec import parse_crossing
from rig.simulators.urlhandler import get_world, register
from tests.sim.hosts import SPECS, Port

pytestmark = pytest.mark.usefixtures("sim_ports")


def test_register_is_idempotent() -> None:
    register()
    register()
    assert serial.protocol_handler_packages.count("rig.simulators.urlhandler") == 1


def test_a_shot_through_three_ports_of_one_rig() -> None:
    url = "sim://{}?scene=ideal&rig=bench"
    cannon, gates, clamp = (Port(url.format(d), d) for d in ("cannon", "gates", "clamp"))
    clamp.ask("CLAMP")
    clamp.wait_event("LOCK")
    gates.ask("ARM")
    cannon.ask("PSET", 395.0)
    cannon.wait_event("READY")
    cannon.ask("ARM")
    cannon.ask("FIRE")
    breaks = [parse_crossing(gates.wait_event("G")).gate for _ in range(6)]
    assert breaks == [1, 2, 3, 3, 2, 1]
    assert len(get_world("bench").shots) == 1
    with pytest.raises(KeyError):
        get_world("default")  # another rig name, another world: none opened here


def test_read_honours_the_timeout_and_wakes_when_data_comes() -> None:
    port = serial.serial_for_url("sim://gates", timeout=0.2)
    t0 = time.monotonic()
    assert port.read(10) == b""
    assert 0.15 < time.monotonic() - t0 < 1.0
    port.timeout = 5.0
    other = get_world("default")
    codec = HostCodec(SPECS["gates"])

    def later() -> None:
        time.sleep(0.1)
        other.gates.write(codec.command("ID")[1])  # as if another thread of the host wrote

    threading.Thread(target=later).start()
    t0 = time.monotonic()
    data = port.read(500)
    assert data.startswith(b"1 OK MODEL=SIM-GATES") and time.monotonic() - t0 < 2.0
    assert port.in_waiting == 0


def test_unplug_mid_shot_raises_until_the_port_is_reopened(tmp_path: Path) -> None:
    scene = tmp_path / "unplug.toml"
    scene.write_text('[[effects]]\nkind = "unplug"\nshots = [1]\ndevice = "gates"\nafter = 2\n')
    url = "sim://{}?scene=" + str(scene) + "&rig=u"
    cannon, gates, clamp = (Port(url.format(d), d) for d in ("cannon", "gates", "clamp"))
    clamp.ask("CLAMP")
    clamp.wait_event("LOCK")
    gates.ask("ARM")
    cannon.ask("PSET", 395.0)
    cannon.wait_event("READY")
    cannon.ask("ARM")
    cannon.ask("FIRE")
    assert [parse_crossing(gates.wait_event("G")).gate for _ in range(2)] == [1, 2]
    with pytest.raises(serial.SerialException, match="device unplugged"):
        gates.port.read(1)
    with pytest.raises(serial.SerialException, match="device unplugged"):
        gates.port.write(b"x")
    gates.port.close()
    gates = Port(url.format("gates"), "gates")
    assert gates.ask("ID").named()["MODEL"] == "SIM-GATES"


def test_bad_urls_are_refused_clearly() -> None:
    with pytest.raises(serial.SerialException, match="device must be one of"):
        serial.serial_for_url("sim://toaster")
    with pytest.raises(serial.SerialException, match="unknown sim:// option"):
        serial.serial_for_url("sim://gates?scnee=lab")
    with pytest.raises(ConfigError, match="no such scene file"):
        serial.serial_for_url("sim://gates?scene=nowhere.toml&rig=x")
    held = serial.serial_for_url("sim://gates?rig=y")  # keep it: closing on collection frees it
    with pytest.raises(serial.SerialException, match="already open"):
        held = serial.serial_for_url("sim://gates?rig=y")  # keep it: closing on collection frees it
    with pytest.raises(serial.SerialException, match="already runs scene"):
        serial.serial_for_url("sim://cannon?scene=lab&rig=y")
    held.close()
    serial.serial_for_url("sim://gates?rig=y").close()  # free again once closed
