"""A simulated cannon PLC: pymodbus's own Modbus server in front of a SimWorld's SimCannon.

On TCP by default; with `serial=True` the server speaks RTU frames (unit, PDU, CRC-16) and a pty
in front of it (rig.simulators.ptybridge) is the serial port the driver opens, as a USB adapter.

The registers are drivers/modbus/plc_codec.py's map. Every read is filled from the world's cannon at
that moment; every write goes to the cannon's own logic (SimCannon.pset/arm/fire/vent/reset), so the
PLC refuses FIRE with an interlock open exactly as the line protocol's cannon does, whatever a driver
decided (a refusal is exception 4, SERVER DEVICE FAILURE). Virtual time: a read of the pressure
while the tank fills moves the world's clock to the fill's READY, at most `poll_limit_s` per read.

Faults (keyword options, for tests): `exception_at=(function, address)` answers that request with
`exception_code` instead of acting; `drop_at=(function, address)` carries the request out, then
drops the connection before the reply; either strikes `fault_times` times, only once the command
`fault_after` (e.g. "ARM") has been accepted if given. `door_opens_after_arm` opens the enclosure
door right after each accepted ARM (world.set_interlock): the interlock chain then vents the tank.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Mapping
from typing import Any, ClassVar

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.pdu.device import ModbusDeviceIdentification
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from rig.core.devices import CannonState, Environment
from rig.drivers.cannon.codec import refuse_in_state
from rig.drivers.modbus import plc_codec as plc
from rig.simulators.ptybridge import PtyBridge
from rig.simulators.world import SimWorld

IDENTITY = {"VendorName": "bat-rig simulator", "ProductCode": "SIM-PLC", "MajorMinorRevision": "sim-1"}
MODEL_NAME, SERIAL = "SIM-CANNON-PLC", "SIM-P001"
START_TIMEOUT_S = 30.0  # the server thread must be listening within this (wall) time
REPLY_TIMEOUT_S = 30.0  # the driver's time limit for a reply from the twin (device_table)


class ModbusPlcTwin:
    """The cannon PLC of `world` on a local Modbus TCP port."""

    DRIVER: ClassVar[str] = "modbus-cannon"
    KIND: ClassVar[str] = "cannon"
    SERIAL: ClassVar[bool] = True  # serial=True serves it on a pty

    def __init__(
        self,
        world: SimWorld,
        *,
        unit: int = 1,
        registers: Mapping[str, int] | None = None,
        exception_at: tuple[int, int] | None = None,
        exception_code: int = int(ExcCodes.DEVICE_FAILURE),
        drop_at: tuple[int, int] | None = None,
        fault_after: str | None = None,
        fault_times: int = 1,
        door_opens_after_arm: bool = False,
        poll_limit_s: float = 60.0,
        serial: bool = False,
    ) -> None:
        self.transport = "rtu" if serial else "tcp"  # serial: RTU frames, on a pty in front of the server
        self.bridge: PtyBridge | None = None
        self.tcp_address = ""  # RTU: where the server itself listens (RTU frames over TCP)
        self.world = world
        self.unit = plc.check_unit(unit)
        self.regs = plc.RegisterMap.from_options(registers or {})
        self.exception_at, self.exception_code, self.drop_at = exception_at, exception_code, drop_at
        self.fault_after, self.faults_left = fault_after, fault_times
        self.door_opens_after_arm = door_opens_after_arm
        self.poll_limit_s = poll_limit_s  # [assumed] the PLC's own bound on one wait for the fill
        self.last_command = 0
        self.commands: list[str] = []  # every command accepted, in order (tests read it)
        self.refusals: list[str] = []  # every command refused, with the reason
        self.address = ""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._thread: threading.Thread | None = None
        self._stop: asyncio.Event | None = None

    # -- the twin API ---------------------------------------------------------------------------
    def start(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Serve in a daemon thread; the address the driver connects to (host:port, or for RTU the
        pty's path)."""
        ready = threading.Event()
        failure: list[BaseException] = []
        self._thread = threading.Thread(
            target=self._run, args=(host, port, ready, failure), name="modbus-plc-twin", daemon=True
        )
        self._thread.start()
        if not ready.wait(START_TIMEOUT_S) or failure:
            raise RuntimeError(
                f"simulated PLC did not start on {host}:{port}: {failure[0] if failure else 'timeout'}"
            )
        if self.transport == "rtu":
            self.tcp_address = self.address
            bound_host, _, bound_port = self.address.rpartition(":")
            self.bridge = PtyBridge(bound_host, int(bound_port))
            self.address = self.bridge.start()
        return self.address

    def device_table(self) -> dict[str, Any]:
        """The [devices.cannon] table of a rig config that uses this twin."""
        table = {name: getattr(self.regs, name) for name in self.regs.__dataclass_fields__}
        return {
            "driver": self.DRIVER,
            "address": self.address,
            # a reply waits for the simulated physics (a shot's collision), seconds on a busy machine
            "options": {
                "unit": self.unit,
                "registers": table,
                "poll_s": 0.01,
                "timeout_s": REPLY_TIMEOUT_S,
                # a pty takes no parity (its termios refuses PARENB): the spec's no-parity form, 2 stop bits
                **(
                    {"transport": "rtu", "baud": 115200, "parity": "N", "stopbits": 2}
                    if self.transport == "rtu"
                    else {}
                ),
            },
            "simulated": True,
        }

    def close(self) -> None:
        """Stop serving (open connections are closed)."""
        if self.bridge is not None:
            self.bridge.close()
        if self._loop is not None and self._stop is not None and self._loop.is_running():
            self._loop.call_soon_threadsafe(self._stop.set)
        if self._thread is not None:
            self._thread.join(START_TIMEOUT_S)
            self._thread = None

    def drop_connections(self) -> None:
        """Drop every client connection now (from the server's own thread)."""
        if self._loop is not None:
            self._loop.call_soon_threadsafe(self._drop)

    # -- the server -----------------------------------------------------------------------------
    def _run(self, host: str, port: int, ready: threading.Event, failure: list[BaseException]) -> None:
        loop = self._loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._serve(host, port, ready))
        except BaseException as exc:  # reported to start(); a thread must not die silently
            failure.append(exc)
            ready.set()
        finally:
            loop.close()

    async def _serve(self, host: str, port: int, ready: threading.Event) -> None:
        size = max(getattr(self.regs, n) for n in self.regs.__dataclass_fields__) + plc.BALL_REGISTERS
        device = SimDevice(
            id=self.unit,
            simdata=[SimData(0, count=size, values=0, datatype=DataType.REGISTERS)],
            action=self._action,
        )
        identity = ModbusDeviceIdentification(
            info_name={**IDENTITY, "ModelName": MODEL_NAME}, info={0x80: SERIAL}
        )
        self._stop = asyncio.Event()
        framer = FramerType.RTU if self.transport == "rtu" else FramerType.SOCKET
        self._server = server = ModbusTcpServer(
            device, address=(host, port), identity=identity, framer=framer
        )
        await server.serve_forever(background=True)
        sock = server.transport.sockets[0]  # type: ignore[attr-defined]  # a listening asyncio Server
        self.address = f"{host}:{sock.getsockname()[1]}"
        ready.set()
        await self._stop.wait()
        await server.shutdown()
        for _ in range(3):  # a connection accepted while the listener closed is dropped too; the
            self._drop()  # loop runs on a little, so that the dropped sockets really close
            await asyncio.sleep(0.02)

    def _drop(self) -> None:
        if self._server is not None:
            for conn in list(self._server.active_connections.values()):
                if isinstance(conn.transport, asyncio.WriteTransport):
                    conn.transport.abort()  # at once, as a pulled cable: nothing more goes out
                conn.close()

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        current_registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        """Every request: faults first, then a write to the cannon's logic or a read of it."""
        # a write's reply echoes the register: pymodbus reads it back through here after the write
        echo = set_values is None and function_code in (6, 16)
        if not echo and self._strikes(self.exception_at, function_code, address, count):
            return ExcCodes(self.exception_code)
        dropping = not echo and self._strikes(self.drop_at, function_code, address, count)
        with self.world.lock:
            if set_values is not None:
                result = self._write(address, [int(v) for v in set_values])
            else:
                self._fill(start_address, address, count, current_registers)
                result = None
            self.world.cannon.out.discard_due(self.world.clock)  # no line host reads the cannon's events
            self.world.changed.notify_all()
        if dropping:
            self._drop()
        return result

    def _strikes(self, where: tuple[int, int] | None, function: int, address: int, count: int) -> bool:
        if where is None or self.faults_left <= 0 or function != where[0]:
            return False
        if not address <= where[1] < address + count:
            return False
        if self.fault_after is not None and self.fault_after not in self.commands:
            return False
        self.faults_left -= 1
        return True

    def _fill(self, start: int, address: int, count: int, registers: list[int]) -> None:
        cannon, world = self.world.cannon, self.world
        if address <= self.regs.pressure < address + count:
            ready = cannon.ready_at
            if cannon.state is CannonState.SAFE and ready is not None and ready > world.clock:
                world.advance_to(min(ready, world.clock + self.poll_limit_s))
        values = plc.status_registers(self.regs, cannon.status(), plc.fault_count(cannon.fault_code))
        values.update(plc.environment_registers(self.regs, _environment(world)))
        values[self.regs.command] = self.last_command
        for reg, value in values.items():
            if address <= reg < address + count:
                registers[reg - start] = value

    def _write(self, address: int, values: list[int]) -> ExcCodes | None:
        if address == self.regs.ball:  # the ball id, written whole in one request
            return self._load(values)
        for offset, value in enumerate(values):
            reg = address + offset
            if reg == self.regs.setpoint:
                kpa = value * plc.PRESSURE_LSB_KPA
                if kpa > plc.MAX_PRESSURE_KPA:
                    return self._refused("PSET", f"{kpa:g} kPa is above the range", ExcCodes.ILLEGAL_VALUE)
                refusal = self.world.cannon.pset(kpa)
                verb = "PSET"
            elif reg == self.regs.command:
                verb = plc.COMMAND_NAMES.get(value, "")
                if not verb:
                    return self._refused(f"command {value}", "no such command", ExcCodes.ILLEGAL_VALUE)
                refusal = self._command(verb)
            else:
                return self._refused(f"write at {reg}", "read-only register", ExcCodes.ILLEGAL_ADDRESS)
            if refusal is not None:
                return self._refused(verb, f"{refusal[0]} {refusal[1]}", ExcCodes.DEVICE_FAILURE)
            self.commands.append(verb)
            if reg == self.regs.command:
                self.last_command = value
        return None

    def _load(self, values: list[int]) -> ExcCodes | None:
        """LOAD: the ball in the breech, for the world's own record of each shot's ball."""
        if len(values) != plc.BALL_REGISTERS:
            return self._refused(
                "LOAD", f"{len(values)} registers, not {plc.BALL_REGISTERS}", ExcCodes.ILLEGAL_VALUE
            )
        try:
            ball_id = plc.decode_ball(values)
        except ValueError:
            return self._refused("LOAD", "not an ASCII ball id", ExcCodes.ILLEGAL_VALUE)
        reason = refuse_in_state("LOAD", self.world.cannon.state)
        if reason is not None or not ball_id:
            return self._refused("LOAD", reason or "an empty ball id", ExcCodes.DEVICE_FAILURE)
        self.world.load_ball(ball_id)
        self.commands.append("LOAD")
        return None

    def _command(self, verb: str) -> tuple[str, str] | None:
        cannon = self.world.cannon
        if verb == "VENT":
            cannon.vent()
            return None
        refusal = {"ARM": cannon.arm, "FIRE": cannon.fire, "RESET": cannon.reset}[verb]()
        if verb == "ARM" and refusal is None and self.door_opens_after_arm:
            self.world.set_interlock("door", False)
        return refusal

    def _refused(self, what: str, why: str, code: ExcCodes) -> ExcCodes:
        self.refusals.append(f"{what}: {why}")
        return code


def _environment(world: SimWorld) -> Environment:
    temp, rh = world.lab.environment(world.clock)
    return Environment(temp, rh)
