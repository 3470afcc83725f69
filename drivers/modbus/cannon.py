"""The air cannon on a PLC over Modbus TCP or RTU (driver `modbus-cannon`; a rig.core.devices.Cannon).

Every decision is taken on one fresh read of the status block (state, pressure, setpoint,
interlocks, shot counter, fault: one Read Holding Registers): FIRE is written only when that read,
made immediately before, succeeded, shows no PLC fault, and the cannon codec's `refuse_fire` says
nothing; the PLC refuses again if the driver is wrong, and its interlock chain must be hard-wired too.
No request is retried, so no command can reach the PLC twice.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Self

from rig.core.devices import CannonStatus, Environment, InstrumentIdentity
from rig.core.errors import DeviceError, DeviceTimeout, GarbledReply, NotSent, ParameterError, SafetyRefusal
from rig.drivers.cannon import codec
from rig.drivers.modbus import plc_codec as plc
from rig.drivers.modbus.transport import LINE_OPTIONS, TRANSPORTS, ModbusTransport, SerialLine
from rig.drivers.registry import DriverContext
from rig.drivers.traffic import TrafficRecord

DEFAULT_POLL_S = 0.2  # [assumed] between pressure reads while the tank fills
# Read Device Identification objects: 0 vendor, 1 product code, 2 revision, 5 model; 0x80 (private)
# the serial number [assumed: no standard object holds it]
VENDOR, PRODUCT_CODE, REVISION, MODEL, SERIAL = 0x00, 0x01, 0x02, 0x05, 0x80


class ModbusCannon:
    """The cannon's PLC: registers per `plc_codec.RegisterMap`, one unit of a Modbus TCP server, or
    of an RTU line when `serial` gives the line's settings."""

    def __init__(
        self,
        address: str,
        *,
        unit: int = 1,
        registers: plc.RegisterMap | None = None,
        name: str = "cannon",
        reply_timeout_s: float = 1.0,
        ready_timeout_s: float = 120.0,
        poll_s: float = DEFAULT_POLL_S,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        serial: SerialLine | None = None,
    ) -> None:
        self.name = name
        self.regs = registers or plc.RegisterMap()
        self.ready_timeout_s = ready_timeout_s
        self.poll_s = poll_s
        self.transport = ModbusTransport(
            name, address, unit, timeout_s=reply_timeout_s, on_traffic=on_traffic, serial=serial
        )

    @classmethod
    def from_context(cls, context: DriverContext) -> Self:
        """The `modbus-cannon` driver of a rig config: options unit, registers, poll_s, timeout_s (a
        reply's time limit for this PLC, instead of the rig's timeouts.reply_s), transport ("tcp",
        the default, or "rtu": the address is then a serial port) and, for RTU, baud, parity, stopbits."""
        known: dict[str, type | tuple[type, ...]] = {
            "unit": int,
            "registers": dict,
            "poll_s": (int, float),
            "timeout_s": (int, float),
            "transport": str,
            "baud": int,
            "parity": str,
            "stopbits": int,
        }
        options = context.only_options(known)
        transport = options.get("transport", "tcp")
        if transport not in TRANSPORTS:
            raise context.refuse(
                f"modbus-cannon: transport {transport!r} must be one of {', '.join(TRANSPORTS)}"
            )
        line_options = [name for name in LINE_OPTIONS if name in options]
        if transport == "tcp" and line_options:
            raise context.refuse(f'modbus-cannon: option {line_options[0]!r} is for transport = "rtu"')
        try:
            unit = plc.check_unit(options.get("unit", 1))
            regs = plc.RegisterMap.from_options(options.get("registers", {}))
            serial = SerialLine(**{n: options[n] for n in line_options}) if transport == "rtu" else None
        except ValueError as exc:
            raise context.refuse(f"modbus-cannon: {exc}") from None
        poll_s = float(options.get("poll_s", DEFAULT_POLL_S))
        if not 0.0 < poll_s <= 10.0:
            raise context.refuse(f"modbus-cannon: poll_s {poll_s:g} must be above 0 and at most 10 s")
        timeout_s = float(options.get("timeout_s", context.timeouts.reply_s))
        if not 0.05 <= timeout_s <= 60.0:
            raise context.refuse(f"modbus-cannon: timeout_s {timeout_s:g} must be 0.05-60 s")
        try:
            return cls(
                context.address,
                unit=unit,
                registers=regs,
                name=context.name,
                reply_timeout_s=timeout_s,
                ready_timeout_s=context.timeouts.pressure_ready_s,
                poll_s=poll_s,
                on_traffic=context.on_traffic,
                serial=serial,
            )
        except ValueError as exc:
            raise context.refuse(f"modbus-cannon: {exc}") from None

    # -- reads ------------------------------------------------------------------------------
    def plc_status(self) -> plc.PlcStatus:
        """One read of the status block, decoded (GarbledReply naming a register with a bad value)."""
        start, count = self.regs.status_block()
        values = self.transport.read_holding(start, count)
        try:
            return plc.decode_status(self.regs, start, values)
        except ValueError as exc:
            raise GarbledReply(self.name, f"status block: {exc}") from None

    def status(self) -> CannonStatus:
        """A fresh read: state, pressure, setpoint, interlocks (net and breech in door), shots."""
        return self.plc_status().status

    def environment(self) -> Environment:
        """Lab temperature and relative humidity (the PLC's sensors)."""
        start, count = self.regs.environment_block()
        return plc.decode_environment(self.regs, start, self.transport.read_holding(start, count))

    def identify(self) -> InstrumentIdentity:
        """Read Device Identification (function 43/14): model, revision, serial, vendor."""
        objects = self.transport.device_identification()

        def text(key: int) -> str:
            return objects.get(key, b"").decode("utf-8", "replace").strip()

        return InstrumentIdentity(
            model=text(MODEL) or text(PRODUCT_CODE),
            firmware=text(REVISION),
            serial_number=text(SERIAL),
            maker=text(VENDOR),
        )

    # -- commands ---------------------------------------------------------------------------
    def set_pressure(self, kpa: float, wait_ready: bool = True) -> None:
        """Write the setpoint (SAFE only); with `wait_ready`, poll until the pressure is within the
        codec's ready band of it, bounded by the rig's pressure_ready_s."""
        try:
            codec.SPECS["PSET"].check(kpa)
            count = plc.pressure_count(float(kpa))
        except ValueError as exc:
            raise ParameterError(f"{self.name} PSET", (kpa,), str(exc)) from None
        now = self.plc_status()
        reason = codec.refuse_in_state("PSET", now.status.state)
        if reason is not None:
            raise NotSent(self.name, "PSET", reason)
        self.transport.write_register(self.regs.setpoint, count)
        if not wait_ready:
            return
        setpoint = count * plc.PRESSURE_LSB_KPA
        deadline = time.monotonic() + self.ready_timeout_s
        while True:
            now = self.plc_status()
            if now.fault:
                raise DeviceError(self.name, f"fault {now.fault_name} while filling to {setpoint:.1f} kPa")
            if codec.pressure_ready(now.status.pressure_kpa, setpoint) or setpoint <= 0:
                return
            if time.monotonic() >= deadline:
                raise DeviceTimeout(
                    self.name,
                    f"pressure {now.status.pressure_kpa:.1f} kPa not at {setpoint:.1f} kPa "
                    f"after {self.ready_timeout_s:g} s",
                )
            time.sleep(self.poll_s)

    def load_ball(self, ball_id: str) -> None:
        """Tell the PLC which ball is in the breech (SAFE only): its id in the ball registers, one
        write, so that the PLC's record (and a simulated world) knows the ball of each shot."""
        try:
            codec.SPECS["LOAD"].check(ball_id)
            values = plc.encode_ball(ball_id)
        except ValueError as exc:
            raise ParameterError(f"{self.name} LOAD", (ball_id,), str(exc)) from None
        reason = codec.refuse_in_state("LOAD", self.plc_status().status.state)
        if reason is not None:
            raise NotSent(self.name, "LOAD", reason)
        self.transport.write_registers(self.regs.ball, values)

    def arm(self) -> None:
        """SAFE -> ARMED; written only if a fresh read shows no fault and refuse_arm allows it."""
        reason = plc.refuse_plc_arm(self._read_before("ARM"))
        if reason is not None:
            raise SafetyRefusal(self.name, f"ARM not sent: {reason}")
        self.transport.write_register(self.regs.command, plc.COMMANDS["ARM"])

    def fire(self) -> int:
        """Fire and return the shot counter; FIRE is written only if the read just before it
        succeeded, shows no fault, and refuse_fire allows it."""
        before = self._read_before("FIRE")
        reason = plc.refuse_plc_fire(before)
        if reason is not None:
            raise SafetyRefusal(self.name, f"FIRE not sent: {reason}")
        self.transport.write_register(self.regs.command, plc.COMMANDS["FIRE"])
        after = self.plc_status()
        if after.fault:
            raise DeviceError(self.name, f"fault {after.fault_name} after FIRE")
        if after.status.shots == before.status.shots:
            raise DeviceError(self.name, f"FIRE accepted but the shot counter stayed at {after.status.shots}")
        return after.status.shots

    def vent(self) -> None:
        """Dump the tank and return to SAFE (always allowed, written at once)."""
        self.transport.write_register(self.regs.command, plc.COMMANDS["VENT"])

    def reset(self) -> None:
        """FAULT -> SAFE; not written unless the PLC reports FAULT."""
        reason = codec.refuse_in_state("RESET", self.status().state)
        if reason is not None:
            raise NotSent(self.name, "RESET", reason)
        self.transport.write_register(self.regs.command, plc.COMMANDS["RESET"])

    def _read_before(self, verb: str) -> plc.PlcStatus:
        """The read a command is decided on; a failed read refuses the command (SafetyRefusal)."""
        try:
            return self.plc_status()
        except DeviceError as exc:
            raise SafetyRefusal(
                self.name, f"{verb} not sent: the status read before it failed: {exc}"
            ) from exc

    # -- lifecycle --------------------------------------------------------------------------
    def close(self) -> None:
        """Close the connection."""
        self.transport.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def registers_table(regs: plc.RegisterMap) -> Mapping[str, int]:
    """A register map as the `registers` option writes it."""
    return {name: getattr(regs, name) for name in regs.__dataclass_fields__}
