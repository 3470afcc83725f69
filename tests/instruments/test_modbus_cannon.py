"""The cannon on a PLC over Modbus TCP: codec, driver against the simulated PLC over real TCP, safety,
faults, and a whole certification with the cannon on the twin and the gates and clamp on sim://.

Numbers are checked against what does not come from the code under test: the Modbus spec's byte
layout of a request, the scene's fill rate and muzzle-speed law, the world's ShotTruth.
"""

from __future__ import annotations

import base64
import struct
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.config import Devices, DeviceSpec, RigConfig
from rig.core.devices import CannonState, CannonStatus, Environment, Interlocks
from rig.core.errors import ConfigError, DeviceError, DeviceGone, DeviceRefused, SafetyRefusal
from rig.drivers.modbus import plc_codec as plc
from rig.drivers.modbus.cannon import ModbusCannon
from rig.drivers.registry import DriverContext, open_device
from rig.drivers.traffic import TrafficRecord
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.simulators.instruments.modbus_plc import ModbusPlcTwin
from rig.simulators.scene import Scene
from rig.simulators.urlhandler import get_world
from rig.simulators.world import SimWorld
from rig.store import Store
from tests.instruments.attempts import fire_with_an_interlock_open
from tests.protocols.wire import expected_stage_mm

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
P = 395.0
REGS = plc.RegisterMap()
FIRE_WRITE = struct.pack(">BHH", 6, REGS.command, plc.COMMANDS["FIRE"])  # function 6, address, value


# -- the codec -------------------------------------------------------------------------------------


def test_default_map_and_its_one_status_read() -> None:
    assert REGS.status_block() == (0, 6)
    assert REGS.environment_block() == (6, 2)
    moved = plc.RegisterMap.from_options({"state": 100, "fault": 110, "command": 200})
    assert moved.status_block() == (1, 110)  # pressure stays at 1: one read from 1 to 110


@pytest.mark.parametrize(
    ("table", "why"),
    [
        ({"valve": 3}, "no register 'valve'"),
        ({"state": 1}, "two registers share address 1"),
        ({"state": -1}, "must be an address 0-65535"),
        ({"fault": 400}, "they must fit one read of 125"),
        ({"shots": True}, "must be an address"),
    ],
)
def test_a_bad_register_map_is_refused_naming_why(table: dict[str, Any], why: str) -> None:
    with pytest.raises(ValueError, match=why):
        plc.RegisterMap.from_options(table)


@pytest.mark.parametrize("unit", [0, 248, -1, "1", True])
def test_unit_0_broadcast_and_out_of_range_units_are_refused(unit: object) -> None:
    with pytest.raises(ValueError) as info:
        plc.check_unit(unit)
    if unit == 0 and unit is not True:
        assert "broadcast" in str(info.value)


statuses = st.builds(
    CannonStatus,
    state=st.sampled_from(list(CannonState)),
    pressure_kpa=st.integers(0, 10000).map(lambda n: n / 10),
    setpoint_kpa=st.integers(0, 10000).map(lambda n: n / 10),
    interlocks=st.builds(Interlocks, st.booleans(), st.booleans(), st.booleans()),
    shots=st.integers(0, 65535),
)


@settings(max_examples=200, deadline=None)
@given(statuses, st.integers(0, 2))
def test_status_registers_round_trip(status: CannonStatus, fault: int) -> None:
    regs = plc.status_registers(REGS, status, fault)
    start, count = REGS.status_block()
    values = [regs[a] for a in range(start, start + count)]
    back = plc.decode_status(REGS, start, values)
    assert back.status == status and back.fault == fault


def test_net_and_breech_fold_into_the_door_and_are_named() -> None:
    status = CannonStatus(CannonState.ARMED, P, P, Interlocks(True, True, True), 3)
    bits = plc.interlock_bits(True, True, True, net=False, breech=True)
    got = plc.decode_status(REGS, 0, [plc.status_registers(REGS, status, 0, bits)[a] for a in range(6)])
    assert got.status.interlocks == Interlocks(door=False, clamp=True, estop=True)
    assert plc.refuse_plc_fire(got) == "interlock open: net"


def test_a_plc_fault_refuses_fire_and_arm_even_with_everything_else_right() -> None:
    armed = CannonStatus(CannonState.ARMED, P, P, Interlocks(True, True, True), 0)
    ok = plc.PlcStatus(armed, 0, plc.ALL_CLOSED)
    assert plc.refuse_plc_fire(ok) is None
    assert plc.refuse_plc_fire(plc.PlcStatus(armed, 2, plc.ALL_CLOSED)) == "PLC reports fault SENSOR"
    safe = CannonStatus(CannonState.SAFE, P, P, Interlocks(True, True, True), 0)
    assert plc.refuse_plc_arm(plc.PlcStatus(safe, 9, plc.ALL_CLOSED)) == "PLC reports fault code 9"


@pytest.mark.parametrize(
    ("values", "why"), [([7, 0, 0, 31, 0, 0], "not a state"), ([0, 0, 0, 0x40, 0, 0], "bits")]
)
def test_impossible_register_values_are_refused(values: list[int], why: str) -> None:
    with pytest.raises(ValueError, match=why):
        plc.decode_status(REGS, 0, values)


@pytest.mark.parametrize("temp", [-12.34, 0.0, 21.5, 45.67])
def test_environment_round_trip_with_signed_temperature(temp: float) -> None:
    env = Environment(temp, 48.3)
    regs = plc.environment_registers(REGS, env)
    assert plc.decode_environment(REGS, 6, [regs[6], regs[7]]) == env


def test_frames_split_as_the_modbus_tcp_spec_lays_them_out() -> None:
    # MBAP: transaction 7, protocol 0, length 6, unit 1; PDU: read holding registers from 0, count 6
    request = bytes.fromhex("0007 0000 0006 01 03 0000 0006")
    frames, rest = plc.split_frames(request + request[:5])
    assert rest == request[:5]
    assert frames == [plc.Frame(7, 1, 3, bytes.fromhex("00000006"))]
    fire = plc.Frame(8, 1, 6, FIRE_WRITE[1:])
    assert plc.written_command(fire, REGS) == "FIRE"


# -- the driver against the simulated PLC, over TCP --------------------------------------------------


@pytest.fixture
def world() -> SimWorld:
    return SimWorld(Scene.load("ideal"))


@pytest.fixture
def twin(world: SimWorld) -> Iterator[ModbusPlcTwin]:
    plc_twin = ModbusPlcTwin(world)
    plc_twin.start()
    yield plc_twin
    plc_twin.close()


class Wire:
    """A driver's recorded traffic."""

    def __init__(self) -> None:
        self.records: list[TrafficRecord] = []

    def frames(self, direction: str) -> list[plc.Frame]:
        data = b"".join(r.data for r in self.records if r.direction == direction)
        frames, rest = plc.split_frames(data)
        assert rest == b""
        return frames

    def fires(self) -> int:
        return sum(plc.written_command(f, REGS) == "FIRE" for f in self.frames("tx"))


def driver(address: str, wire: Wire | None = None, **kw: Any) -> ModbusCannon:
    record = (wire or Wire()).records.append
    return ModbusCannon(address, poll_s=0.01, reply_timeout_s=10.0, on_traffic=record, **kw)


def ready(world: SimWorld, cannon: ModbusCannon) -> None:
    """Bat clamped, tank filled to P (the world's clock moves to the fill's end)."""
    world.set_interlock("clamp", True)
    cannon.set_pressure(P)


def test_identify_reads_device_identification(twin: ModbusPlcTwin) -> None:
    with driver(twin.address) as cannon:
        ident = cannon.identify()
    assert (ident.maker, ident.model, ident.firmware, ident.serial_number) == (
        "bat-rig simulator",
        "SIM-CANNON-PLC",
        "sim-1",
        "SIM-P001",
    )


def test_a_shot_through_the_plc_against_the_closed_forms(world: SimWorld, twin: ModbusPlcTwin) -> None:
    wire = Wire()
    with driver(twin.address, wire) as cannon:
        ready(world, cannon)
        fill = P / world.scene.cannon.fill_rate_kpa_s + world.scene.cannon.settle_s
        assert world.clock == pytest.approx(fill, abs=1e-9)  # the poll waited (virtually) for READY
        cannon.arm()
        assert cannon.fire() == 1
        assert cannon.status().shots == 1
        env = cannon.environment()
    assert len(world.shots) == 1
    truth = world.shots[0]
    assert truth.pressure_kpa == P
    assert truth.launch_speed == pytest.approx(world.scene.cannon.muzzle_speed(P), rel=1e-12)
    temp, rh = world.lab.environment(world.clock)
    assert env == Environment(round(temp, 2), round(rh, 1))
    # the recorded bytes are the wire's frames: every request answered by its own transaction id
    tx, rx = wire.frames("tx"), wire.frames("rx")
    assert [f.transaction for f in tx] == [f.transaction for f in rx]
    assert all(f.unit == 1 for f in tx + rx)
    status_read = struct.pack(">BHH", 3, 0, 6)
    assert sum(bytes([f.function]) + f.data == status_read for f in tx) >= 3
    i = next(i for i, f in enumerate(tx) if bytes([f.function]) + f.data == FIRE_WRITE)
    assert bytes([tx[i - 1].function]) + tx[i - 1].data == status_read  # one status read right before FIRE
    assert wire.fires() == 1


def test_the_ball_in_the_breech_is_named_to_the_plc_when_safe_only(
    world: SimWorld, twin: ModbusPlcTwin
) -> None:
    from rig.core.errors import NotSent

    assert plc.decode_ball(plc.encode_ball("LOT-07-12")) == "LOT-07-12"
    assert len(plc.encode_ball("x" * 40)) == plc.BALL_REGISTERS
    with driver(twin.address) as cannon:
        cannon.load_ball("LOT-07-12")
        assert world.ball_id == "LOT-07-12"
        ready(world, cannon)
        cannon.arm()
        with pytest.raises(NotSent, match="LOAD"):
            cannon.load_ball("LOT-07-13")  # not while ARMED: the ball is the one in the breech
        cannon.vent()
    assert world.ball_id == "LOT-07-12"


def test_unit_0_is_refused_before_anything_is_sent(twin: ModbusPlcTwin) -> None:
    seen: list[TrafficRecord] = []
    context = DriverContext("cannon", "cannon", twin.address, {"unit": 0}, on_traffic=seen.append)
    with pytest.raises(ConfigError) as info:
        open_device("cannon", context, DeviceSpec(driver="modbus-cannon", address=twin.address))
    assert "broadcast" in str(info.value) and "\n" not in str(info.value)
    assert seen == [] and twin.commands == []


def test_an_unknown_option_is_refused_in_one_line(twin: ModbusPlcTwin) -> None:
    context = DriverContext("cannon", "cannon", twin.address, {"slave": 1})
    with pytest.raises(ConfigError, match="does not know option 'slave'"):
        open_device("cannon", context, DeviceSpec(driver="modbus-cannon", address=twin.address))


# -- SAFETY ------------------------------------------------------------------------------------------


def raw_fire(client: ModbusTcpClient) -> bool:
    """A FIRE written straight to the PLC, no driver in between: True if the PLC accepted it."""
    return not client.write_register(REGS.command, plc.COMMANDS["FIRE"], device_id=1).isError()


def test_1000_attempts_to_fire_with_an_interlock_open_fire_nothing(world: SimWorld) -> None:
    twin = ModbusPlcTwin(world, door_opens_after_arm=False)
    after_arm = ModbusPlcTwin(world, door_opens_after_arm=True)
    twin.start(), after_arm.start()
    wire = Wire()
    raw = ModbusTcpClient("127.0.0.1", port=int(twin.address.rsplit(":", 1)[1]), retries=0, timeout=10)
    try:
        with driver(twin.address, wire) as cannon, driver(after_arm.address, wire) as cannon_b:
            refused = fire_with_an_interlock_open(world, cannon, cannon_b, 1000, P, lambda: raw_fire(raw))
            assert cannon.status().shots == 0
    finally:
        raw.close()
        twin.close(), after_arm.close()
    assert refused == {"door": 250, "clamp": 250, "estop": 250, "after-arm": 250}
    assert world.shots == [] and world.cannon.fired == 0 and world.attempts == 0
    assert wire.fires() == 0  # the driver never wrote FIRE
    assert "FIRE" not in twin.commands + after_arm.commands
    assert after_arm.commands.count("ARM") == 250  # the arming really happened each time


def test_a_failed_status_read_before_fire_refuses_it(world: SimWorld) -> None:
    twin = ModbusPlcTwin(world, exception_at=(3, REGS.state), fault_after="ARM")
    twin.start()
    wire = Wire()
    try:
        with driver(twin.address, wire) as cannon:
            ready(world, cannon)
            cannon.arm()
            with pytest.raises(SafetyRefusal) as info:
                cannon.fire()
    finally:
        twin.close()
    text = str(info.value)
    assert "FIRE not sent: the status read before it failed" in text and "exception 4" in text
    assert "unit 1 read holding registers (function 3) at 0" in text and "\n" not in text
    assert wire.fires() == 0 and world.shots == [] and "FIRE" not in twin.commands


def test_a_plc_fault_refuses_fire(world: SimWorld, twin: ModbusPlcTwin) -> None:
    with driver(twin.address) as cannon:
        ready(world, cannon)
        cannon.arm()
        with world.lock:
            world.cannon.fault_code = "SENSOR"  # the PLC reports a sensor fault while armed
        with pytest.raises(SafetyRefusal, match="FIRE not sent: PLC reports fault SENSOR"):
            cannon.fire()
    assert world.shots == []


def test_a_misfire_is_one_line_and_the_next_fire_is_refused() -> None:
    scene = Scene.model_validate({"effects": [{"kind": "misfire", "shots": [1]}]})
    world = SimWorld(scene)
    twin = ModbusPlcTwin(world)
    twin.start()
    try:
        with driver(twin.address) as cannon:
            ready(world, cannon)
            cannon.arm()
            with pytest.raises(DeviceError, match="fault MISFIRE after FIRE"):
                cannon.fire()
            with pytest.raises(SafetyRefusal, match="FIRE not sent: PLC reports fault MISFIRE"):
                cannon.fire()
            cannon.reset()
            assert cannon.plc_status().fault == 0
    finally:
        twin.close()
    assert world.shots == []


def test_an_exception_response_to_fire_is_one_line_and_fires_nothing(world: SimWorld) -> None:
    twin = ModbusPlcTwin(world, exception_at=(6, REGS.command), fault_after="ARM")
    twin.start()
    try:
        with driver(twin.address) as cannon:
            ready(world, cannon)
            cannon.arm()
            with pytest.raises(DeviceRefused) as info:
                cannon.fire()
    finally:
        twin.close()
    assert str(info.value) == (
        "cannon: refused unit 1 write register (function 6) at 8: exception 4 SERVER DEVICE FAILURE"
    )
    assert world.shots == []


def test_a_connection_dropped_after_fire_is_one_line_and_nothing_fires_twice(world: SimWorld) -> None:
    twin = ModbusPlcTwin(world, drop_at=(6, REGS.command), fault_after="ARM")
    twin.start()
    try:
        with driver(twin.address) as cannon:
            ready(world, cannon)
            cannon.arm()
            with pytest.raises(DeviceGone) as info:
                cannon.fire()  # the PLC fired, the reply was lost with the connection
            assert "unit 1 write register (function 6) at 8: connection lost" in str(info.value)
            assert "\n" not in str(info.value)
            status = cannon.status()  # the next request connects again
            assert status.shots == 1 and status.state is not CannonState.ARMED
            with pytest.raises(SafetyRefusal, match="FIRE not sent"):
                cannon.fire()
    finally:
        twin.close()
    assert len(world.shots) == 1


def test_a_vanished_plc_is_device_gone_in_one_line(world: SimWorld) -> None:
    twin = ModbusPlcTwin(world)
    twin.start()
    cannon = driver(twin.address)
    assert cannon.status().shots == 0  # connected, and the PLC has answered on this connection
    twin.close()
    with pytest.raises(DeviceGone) as info:
        cannon.status()
    assert "unit 1 read holding registers (function 3) at 0" in str(info.value)
    cannon.close()


# -- a whole certification: the cannon on the simulated PLC, the gates and clamp on sim:// ------------


def plc_config(rig: str, **faults: Any) -> tuple[RigConfig, ModbusPlcTwin, SimWorld]:
    config = sim_config("lab", rig_name=rig, bat=BAT)  # installs the world of rig `rig`
    world = get_world(rig)
    twin = ModbusPlcTwin(world, **faults)
    twin.start()
    devices = Devices(cannon=DeviceSpec(**twin.device_table()))
    return config.model_copy(update={"devices": devices}), twin, world


def cannon_fires(entries: list[Any]) -> Counter[int]:
    """FIRE writes on the cannon's recorded Modbus traffic per shot, each checked against the stage
    position the clamp was last commanded to (MOVE on the line protocol) in the same session."""
    from rig.drivers.clamp import codec as clamp_codec
    from rig.drivers.codec import CheckedCommand, DeviceCodec

    bat = next(e.payload["bat"] for e in entries if e.kind == "RunStarted")
    where = {e.payload["index"]: e.payload["location_in"] for e in entries if e.kind == "ShotRequested"}
    fires: Counter[int] = Counter()
    stage: float | None = None
    clamp = DeviceCodec(clamp_codec.SPECS)
    pending = b""
    for e in entries:
        if e.kind in ("RunStarted", "RunResumed"):
            stage, clamp, pending = None, DeviceCodec(clamp_codec.SPECS), b""
        if e.kind != "Traffic":
            continue
        for chunk in e.payload["chunks"]:
            if chunk["dir"] != "tx":
                continue
            data = base64.b64decode(chunk["data_b64"])
            if chunk["device"] == "clamp":
                for item in clamp.feed(data):
                    if isinstance(item, CheckedCommand) and item.verb == "MOVE":
                        stage = float(item.values[0])  # type: ignore[arg-type]
            elif chunk["device"] == "cannon":
                frames, pending = plc.split_frames(pending + data)
                for frame in frames:
                    if plc.written_command(frame, REGS) == "FIRE":
                        index = e.payload["index"]
                        assert index in where and stage is not None
                        assert stage == pytest.approx(expected_stage_mm(bat, where[index]), abs=0.01)
                        fires[index] += 1
    return fires


def test_a_certification_with_the_cannon_on_the_simulated_plc(tmp_path: Path) -> None:
    config, twin, world = plc_config("modbus-cert")
    try:
        with Store.open(tmp_path / "r.db") as store:
            started = time.monotonic()
            out = certify(store, Procedure.load("bbcor"), BAT, config)
            took = time.monotonic() - started
            entries = store.entries(out.run_id)
    finally:
        twin.close()
    assert out.status == "finished", out.reason
    assert out.verdict is not None and out.verdict.verdict in ("PASS", "FAIL")
    fires = cannon_fires(entries)
    fired = [e.payload["index"] for e in entries if e.kind == "ShotFired"]
    assert [e for e in entries if e.kind == "ShotLost"] == []
    assert sorted(fires) == sorted(fired) and set(fires.values()) == {1}  # each shot once, at its place
    assert len(world.shots) == len(fired) == twin.commands.count("FIRE")
    chunks = [c for e in entries if e.kind == "Traffic" for c in e.payload["chunks"]]
    rx = b"".join(
        base64.b64decode(c["data_b64"]) for c in chunks if (c["device"], c["dir"]) == ("cannon", "rx")
    )
    frames, rest = plc.split_frames(rx)
    assert rest == b"" and {f.function for f in frames} == {3, 6, 16}  # the record holds the Modbus frames
    # each ball the world launched is the ball the record names for that shot (LOAD, function 16)
    named = [e.payload["ball"] for e in entries if e.kind == "ShotFired"]
    assert [s.ball_id for s in world.shots] == named and twin.commands.count("LOAD") >= len(named)
    print(f"\ncertification through the simulated PLC: {len(fired)} shots in {took:.1f} s")


def test_a_dropped_connection_at_fire_interrupts_the_run_and_it_resumes(tmp_path: Path) -> None:
    config, twin, world = plc_config("modbus-drop", drop_at=(6, REGS.command), fault_after="ARM")
    try:
        with Store.open(tmp_path / "r.db") as store:
            first = certify(store, Procedure.load("bbcor"), BAT, config)
            assert first.status == "interrupted"
            assert "connection lost" in first.reason and "\n" not in first.reason
            lost = [e.payload for e in store.entries(first.run_id) if e.kind == "ShotLost"]
            assert len(lost) == 1 and len(world.shots) == 1  # the PLC fired once; the shot is recorded lost
            again = certify(store, Procedure.load("bbcor"), BAT, config, run_id=first.run_id)
            entries = store.entries(first.run_id)
    finally:
        twin.close()
    assert again.status == "finished", again.reason
    fires = cannon_fires(entries)
    assert set(fires.values()) == {1}  # no shot index fired twice, each at its recorded place
    assert len(world.shots) == sum(fires.values()) == twin.commands.count("FIRE")
