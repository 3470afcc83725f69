"""The cannon's PLC on a Modbus RTU line: the driver opens a serial port (a pty in front of the
simulated PLC, which speaks RTU frames), records the frames raw, refuses FIRE with an interlock open
or when the read before it came back garbled, and certifies a bat through it.

The frames are checked against the Modbus serial-line spec, not against pymodbus or our codec: the
CRC-16 below is written from the spec (polynomial 0xA001, initial 0xFFFF, low byte first) and
checked on the spec's own example.
"""

from __future__ import annotations

import base64
import socket
import struct
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.config import Devices, DeviceSpec
from rig.core.errors import ConfigError, DeviceGone, DeviceTimeout, SafetyRefusal
from rig.drivers.modbus import plc_codec as plc
from rig.drivers.modbus.cannon import ModbusCannon
from rig.drivers.modbus.transport import SerialLine
from rig.drivers.registry import DriverContext
from rig.drivers.traffic import TrafficRecord
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.simulators.instruments.modbus_plc import ModbusPlcTwin
from rig.simulators.ptybridge import PtyBridge
from rig.simulators.scene import Scene
from rig.simulators.urlhandler import get_world
from rig.simulators.world import SimWorld
from rig.store import Store
from tests.instruments.attempts import fire_with_an_interlock_open

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
REGS = plc.RegisterMap()
P = 395.0
LINE = SerialLine(baud=115200, parity="N", stopbits=2)  # a pty refuses parity; the spec's other form
FIRE = (6, struct.pack(">HH", REGS.command, plc.COMMANDS["FIRE"]))


def crc16(data: bytes) -> int:
    """CRC-16/MODBUS as the serial-line spec (6.2.2) computes it."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def test_the_crc_of_the_tests_is_the_specs() -> None:
    # Modbus over Serial Line V1.02, 6.2.2: the frame 02 07 carries CRC 0x1241, sent 41 12
    assert crc16(b"\x02\x07") == 0x1241
    assert crc16(b"\x02\x07\x41\x12") == 0  # a whole frame's CRC over itself is 0


def rtu_requests(chunks: list[bytes]) -> list[tuple[int, int, bytes]]:
    """(unit, function, data) of each request the host sent: every write is one whole frame."""
    out = []
    for frame in chunks:
        assert len(frame) >= 4 and crc16(frame) == 0, frame.hex()
        assert frame[-2:] == struct.pack("<H", crc16(frame[:-2]))  # low byte first
        out.append((frame[0], frame[1], frame[2:-2]))
    return out


def rtu_replies(stream: bytes) -> list[tuple[int, int, bytes]]:
    """The reply frames of `stream`: each ends where its CRC first holds (after the function's
    shortest length); nothing may be left over."""
    out = []
    while stream:
        end = next((n for n in range(5, len(stream) + 1) if crc16(stream[:n]) == 0), None)
        assert end is not None, f"no frame with a good CRC in {stream.hex()}"
        out.append((stream[0], stream[1], stream[2 : end - 2]))
        stream = stream[end:]
    return out


class Wire:
    """A driver's recorded traffic, write by write."""

    def __init__(self) -> None:
        self.records: list[TrafficRecord] = []

    def tx(self) -> list[tuple[int, int, bytes]]:
        return rtu_requests([r.data for r in self.records if r.direction == "tx"])

    def rx(self) -> list[tuple[int, int, bytes]]:
        return rtu_replies(b"".join(r.data for r in self.records if r.direction == "rx"))


@pytest.fixture
def world() -> SimWorld:
    return SimWorld(Scene.load("ideal"))


@pytest.fixture
def twin(world: SimWorld) -> Iterator[ModbusPlcTwin]:
    plc_twin = ModbusPlcTwin(world, serial=True)
    plc_twin.start()
    yield plc_twin
    plc_twin.close()


def driver(address: str, wire: Wire | None = None, timeout_s: float = 10.0) -> ModbusCannon:
    record = (wire or Wire()).records.append
    return ModbusCannon(
        address, poll_s=0.01, reply_timeout_s=timeout_s, on_traffic=record, serial=LINE, unit=1
    )


def test_the_driver_speaks_rtu_frames_on_a_serial_port(world: SimWorld, twin: ModbusPlcTwin) -> None:
    assert twin.address.startswith("/dev/") and twin.address != twin.tcp_address
    wire = Wire()
    with driver(twin.address, wire) as cannon:
        ident = cannon.identify()
        world.set_interlock("clamp", True)
        status = cannon.status()
    assert ident.model == "SIM-CANNON-PLC" and ident.serial_number == "SIM-P001"
    assert status.interlocks.clamp and status.state.value == "SAFE"
    start, count = REGS.status_block()
    assert wire.tx() == [(1, 0x2B, b"\x0e\x03\x00"), (1, 3, struct.pack(">HH", start, count))]
    (unit, function, data), (unit_b, function_b, regs) = wire.rx()
    assert (unit, function, unit_b, function_b) == (1, 0x2B, 1, 3)
    assert b"SIM-CANNON-PLC" in data
    values = struct.unpack(f">{count}H", regs[1:])
    assert regs[0] == 2 * count and values[REGS.interlocks - start] == 0b11111  # all five closed


def test_the_same_driver_reaches_an_rtu_line_behind_a_device_server(twin: ModbusPlcTwin) -> None:
    """A serial device server passes RTU frames through a TCP port: pyserial's socket:// URL."""
    wire = Wire()
    with driver(f"socket://{twin.tcp_address}", wire) as cannon:
        assert cannon.identify().serial_number == "SIM-P001"
    assert [f for _, f, _ in wire.tx()] == [0x2B] and [f for _, f, _ in wire.rx()] == [0x2B]


def test_interlocks_open_fire_nothing_over_rtu(world: SimWorld) -> None:
    plain = ModbusPlcTwin(world, serial=True)
    after_arm = ModbusPlcTwin(world, serial=True, door_opens_after_arm=True)
    plain.start(), after_arm.start()
    wire = Wire()
    try:
        with driver(plain.address, wire) as cannon, driver(after_arm.address, wire) as cannon_b:
            refused = fire_with_an_interlock_open(world, cannon, cannon_b, 100, P)
    finally:
        plain.close(), after_arm.close()
    assert refused == {"door": 25, "clamp": 25, "estop": 25, "after-arm": 25}
    assert world.shots == [] and world.cannon.fired == 0
    assert FIRE not in [(f, d) for _, f, d in wire.tx()]  # the driver never wrote FIRE
    assert after_arm.commands.count("ARM") == 25


def test_a_garbled_reply_before_fire_refuses_it_in_one_line(world: SimWorld, twin: ModbusPlcTwin) -> None:
    assert twin.bridge is not None
    wire = Wire()
    with driver(twin.address, wire, timeout_s=1.0) as cannon:
        world.set_interlock("clamp", True)
        cannon.set_pressure(P)
        cannon.arm()
        twin.bridge.garble_next()  # one bit of the status reply before FIRE flips on the line
        with pytest.raises(SafetyRefusal) as info:
            cannon.fire()
        assert world.shots == [] and FIRE not in [(f, d) for _, f, d in wire.tx()]
        said = str(info.value)
        assert "FIRE not sent" in said and "no valid reply frame" in said and "\n" not in said
        cannon.fire()  # the next read is clean: one FIRE, one launch
    assert len(world.shots) == 1 and [(f, d) for _, f, d in wire.tx()].count(FIRE) == 1


def test_an_unplugged_adapter_is_device_gone_in_one_line(world: SimWorld, twin: ModbusPlcTwin) -> None:
    assert twin.bridge is not None
    with driver(twin.address) as cannon:
        cannon.status()
        twin.bridge.unplug()
        with pytest.raises(DeviceGone) as info:
            cannon.status()
    assert "connection lost" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(DeviceGone) as info:
        driver("/dev/no-such-adapter")
    said = str(info.value)
    assert "cannot connect to Modbus RTU /dev/no-such-adapter" in said and "No such file" in said


def context(**options: Any) -> DriverContext:
    return DriverContext(kind="cannon", name="cannon", address="/dev/ttyUSB9", options=options)


@pytest.mark.parametrize(
    ("options", "said"),
    [
        ({"transport": "udp"}, "transport 'udp' must be one of tcp, rtu"),
        ({"transport": "rtu", "baud": 12345}, "baud 12345 is not a serial rate"),
        ({"transport": "rtu", "parity": "X"}, "parity 'X' must be"),
        ({"transport": "rtu", "stopbits": 3}, "stopbits 3 must be 1 or 2"),
        ({"baud": 9600}, "option 'baud' is for transport = \"rtu\""),
        ({"transport": "rtu", "unit": 0}, "broadcast"),
    ],
)
def test_bad_rtu_options_are_refused_in_one_line(options: dict[str, Any], said: str) -> None:
    with pytest.raises(ConfigError) as info:
        ModbusCannon.from_context(context(**options))
    assert said in str(info.value) and "\n" not in str(info.value)


def test_a_certification_through_the_plc_on_an_rtu_line(tmp_path: Path) -> None:
    config = sim_config("lab", rig_name="modbus-rtu-cert", bat=BAT)
    world = get_world("modbus-rtu-cert")
    twin = ModbusPlcTwin(world, serial=True)
    twin.start()
    devices = Devices(cannon=DeviceSpec(**twin.device_table()))
    config = config.model_copy(update={"devices": devices})
    p = Procedure.load("bbcor")
    procedure = p.model_copy(update={"hits": p.hits.model_copy(update={"valid_hits": 3})})
    try:
        with Store.open(tmp_path / "r.db") as store:
            out = certify(store, procedure, BAT, config)
            entries = store.entries(out.run_id)
    finally:
        twin.close()
    assert out.status == "finished", out.reason
    fires: Counter[int] = Counter()
    for e in entries:
        if e.kind != "Traffic":
            continue
        tx = [
            base64.b64decode(c["data_b64"])
            for c in e.payload["chunks"]
            if (c["device"], c["dir"]) == ("cannon", "tx")
        ]
        fires[e.payload["index"]] += [(f, d) for _, f, d in rtu_requests(tx)].count(FIRE)
    fired = [e.payload["index"] for e in entries if e.kind == "ShotFired"]
    assert {i: n for i, n in fires.items() if n} == dict.fromkeys(fired, 1)  # each shot fired once
    assert len(world.shots) == len(fired) == twin.commands.count("FIRE")
    named = [e.payload["ball"] for e in entries if e.kind == "ShotFired"]
    assert [s.ball_id for s in world.shots] == named
    (identified,) = [e for e in entries if e.kind == "InstrumentsIdentified"]
    assert identified.payload["devices"]["cannon"]["address"] == twin.address


def test_a_parity_the_port_refuses_is_one_line_naming_it(twin: ModbusPlcTwin) -> None:
    with pytest.raises(DeviceGone) as info:
        ModbusCannon(twin.address, serial=SerialLine(parity="E"), reply_timeout_s=1.0)
    said = str(info.value)
    assert "refuses its settings" in said and "8E1" in said and "\n" not in said


def test_bytes_waiting_on_the_line_before_a_request_are_recorded_not_dropped(twin: ModbusPlcTwin) -> None:
    assert twin.bridge is not None
    wire = Wire()
    with driver(twin.address, wire) as cannon:
        cannon.status()
        twin.bridge.inject(b"\x00\xffnoise")
        time.sleep(0.2)  # the noise is on the line before the next request goes out
        cannon.status()
    directions = [(r.direction, r.data) for r in wire.records]
    at = directions.index(("rx", b"\x00\xffnoise"))
    assert directions[at + 1][0] == "tx"  # recorded where it was on the wire: before the request
    assert len(wire.tx()) == 2


def test_noise_before_a_request_that_gets_no_reply_is_a_timeout_not_a_garbled_reply() -> None:
    """Bytes waiting on the line before the request are recorded, but they are not its reply: a PLC
    that then says nothing is DeviceTimeout ("no reply"), not a GarbledReply."""
    silent = socket.create_server(("127.0.0.1", 0))  # accepts (backlog) and never answers
    bridge = PtyBridge("127.0.0.1", silent.getsockname()[1])
    bridge.start()
    wire = Wire()
    try:
        with driver(bridge.path, wire, timeout_s=0.5) as cannon:
            bridge.inject(b"\x00\xffnoise")
            time.sleep(0.2)
            with pytest.raises(DeviceTimeout) as info:
                cannon.status()
    finally:
        bridge.close()
        silent.close()
    assert "no reply" in str(info.value) and "\n" not in str(info.value)
    assert ("rx", b"\x00\xffnoise") in [(r.direction, r.data) for r in wire.records]
