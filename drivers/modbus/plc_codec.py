"""The cannon PLC's Modbus register map, encoding and checks (sans-I/O; docs/instruments/modbus-cannon.md).

Both roles use it: the driver (drivers/modbus/cannon.py) decodes what it reads and refuses a command
before writing it; the simulated PLC (simulators/instruments/modbus_plc.py) encodes the world's cannon
into the same registers. What may happen next is decided by drivers/cannon/codec.py's STATE_TABLE,
`refuse_arm` and `refuse_fire`, with one rule of the PLC's own in front: a reported fault refuses.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass, fields

from rig.core.devices import CannonState, CannonStatus, Environment, Interlocks
from rig.drivers.cannon.codec import MAX_PRESSURE_KPA, refuse_arm, refuse_fire

PRESSURE_LSB_KPA = 0.1  # pressure and setpoint registers: unsigned, 0.1 kPa per count
TEMPERATURE_LSB_C = 0.01  # signed (two's complement), 0.01 degC per count
HUMIDITY_LSB_PCT = 0.1  # unsigned, 0.1 %RH per count
MAX_BLOCK = 125  # registers one Read Holding Registers (function 3) may return
UNIT_RANGE = (1, 247)  # Modbus unit (device) ids; 0 is broadcast: never used

STATE_CODES: dict[int, CannonState] = {
    0: CannonState.SAFE,
    1: CannonState.ARMED,
    2: CannonState.FIRED,
    3: CannonState.FAULT,
}
STATE_VALUES = {state: code for code, state in STATE_CODES.items()}
COMMANDS: dict[str, int] = {"ARM": 1, "FIRE": 2, "VENT": 3, "RESET": 4}  # written to the command register
COMMAND_NAMES = {code: verb for verb, code in COMMANDS.items()}
BALL_REGISTERS = 20  # a ball id of up to 40 characters (drivers/cannon/codec.py BALL_ID_MAX)
FAULT_CODES: dict[int, str] = {0: "", 1: "MISFIRE", 2: "SENSOR"}  # others: reported by number
FAULT_VALUES = {name: code for code, name in FAULT_CODES.items()}

# Interlock register bits, 1 = closed (safe). net and breech are folded into the executor's `door`
# (the enclosure): the door interlock reads closed only when door, net and breech all are.
INTERLOCK_BITS: dict[str, int] = {"door": 0, "clamp": 1, "estop": 2, "net": 3, "breech": 4}
ENCLOSURE = ("door", "net", "breech")
ALL_CLOSED = sum(1 << bit for bit in INTERLOCK_BITS.values())

FUNCTION_NAMES = {
    3: "read holding registers",
    6: "write register",
    16: "write registers",
    43: "read device identification",
}
EXCEPTION_NAMES = {
    1: "ILLEGAL FUNCTION",
    2: "ILLEGAL DATA ADDRESS",
    3: "ILLEGAL DATA VALUE",
    4: "SERVER DEVICE FAILURE",
    5: "ACKNOWLEDGE",
    6: "SERVER DEVICE BUSY",
    10: "GATEWAY PATH UNAVAILABLE",
    11: "GATEWAY TARGET FAILED TO RESPOND",
}


@dataclass(frozen=True)
class RegisterMap:
    """Holding-register addresses (0-based, as on the wire). A lab overrides any through the
    driver's `registers` option; the status block (state .. fault) must fit one read."""

    state: int = 0
    pressure: int = 1
    setpoint: int = 2
    interlocks: int = 3
    shots: int = 4
    fault: int = 5
    temperature: int = 6
    humidity: int = 7
    command: int = 8
    ball: int = 9  # first of BALL_REGISTERS: the id of the ball in the breech, two ASCII characters each

    STATUS = ("state", "pressure", "setpoint", "interlocks", "shots", "fault")

    @classmethod
    def from_options(cls, table: Mapping[str, object]) -> RegisterMap:
        """The default map with `table`'s addresses; ValueError naming a bad name or address."""
        known = [f.name for f in fields(cls)]
        for name, value in table.items():
            if name not in known:
                raise ValueError(f"no register {name!r} (registers: {', '.join(known)})")
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
                raise ValueError(f"register {name!r} must be an address 0-65535, not {value!r}")
        regs = cls(**{k: int(v) for k, v in table.items()})  # type: ignore[call-overload]  # checked above
        addresses = [getattr(regs, n) for n in known]
        if len(set(addresses)) != len(addresses):
            twice = sorted({a for a in addresses if addresses.count(a) > 1})
            raise ValueError(f"two registers share address {twice[0]}")
        inside = [
            n for n in known if n != "ball" and regs.ball <= getattr(regs, n) < regs.ball + BALL_REGISTERS
        ]
        if inside or regs.ball + BALL_REGISTERS > 0x10000:
            raise ValueError(
                f"the ball id takes {BALL_REGISTERS} registers from {regs.ball}"
                + (f": register {inside[0]!r} lies among them" if inside else ": past the last address")
            )
        start, count = regs.status_block()
        if count > MAX_BLOCK:
            raise ValueError(
                f"the status registers ({', '.join(cls.STATUS)}) span {count} addresses from {start}; "
                f"they must fit one read of {MAX_BLOCK}"
            )
        return regs

    def status_block(self) -> tuple[int, int]:
        """(first address, count) of the one read that holds state, pressure, setpoint,
        interlocks, shots and fault."""
        addresses = [getattr(self, n) for n in self.STATUS]
        return min(addresses), max(addresses) - min(addresses) + 1

    def environment_block(self) -> tuple[int, int]:
        """(first address, count) of the read that holds temperature and humidity."""
        lo, hi = sorted((self.temperature, self.humidity))
        return lo, hi - lo + 1


@dataclass(frozen=True)
class PlcStatus:
    """One read of the status block: the cannon's status, the PLC's fault code and the raw bits."""

    status: CannonStatus
    fault: int
    interlock_bits: int

    @property
    def fault_name(self) -> str:
        """The fault's name (MISFIRE, SENSOR) or its number."""
        return FAULT_CODES.get(self.fault) or f"code {self.fault}"

    def open_interlocks(self) -> list[str]:
        """Every open interlock by its own name (net and breech too)."""
        return [n for n, bit in INTERLOCK_BITS.items() if not self.interlock_bits >> bit & 1]


def encode_ball(ball_id: str) -> list[int]:
    """A ball id as BALL_REGISTERS registers: two ASCII characters each, first in the high byte,
    zero-padded; ValueError for a character outside ASCII or an id too long."""
    data = ball_id.encode("ascii")
    if not data or len(data) > 2 * BALL_REGISTERS:
        raise ValueError(f"a ball id is 1-{2 * BALL_REGISTERS} characters, not {len(data)}")
    data = data.ljust(2 * BALL_REGISTERS, b"\0")
    return [data[i] << 8 | data[i + 1] for i in range(0, len(data), 2)]


def decode_ball(registers: list[int]) -> str:
    """The ball id BALL_REGISTERS registers hold (up to the first zero byte); ValueError if not ASCII."""
    data = b"".join(bytes((r >> 8 & 0xFF, r & 0xFF)) for r in registers).split(b"\0", 1)[0]
    return data.decode("ascii")


def check_unit(unit: object) -> int:
    """A Modbus unit id the driver may use; ValueError for 0 (broadcast) or out of 1-247."""
    if isinstance(unit, bool) or not isinstance(unit, int):
        raise ValueError(f"unit must be a whole number 1-247, not {unit!r}")
    if unit == 0:
        raise ValueError("unit 0 is the Modbus broadcast address (no reply, every PLC acts): use 1-247")
    if not UNIT_RANGE[0] <= unit <= UNIT_RANGE[1]:
        raise ValueError(f"unit {unit} is out of the Modbus range 1-247")
    return unit


# -- encoding (the PLC's side) ----------------------------------------------------------------


def pressure_count(kpa: float) -> int:
    """A pressure as its register count (0.1 kPa); ValueError outside 0-1000 kPa."""
    if not 0.0 <= kpa <= MAX_PRESSURE_KPA:
        raise ValueError(f"pressure {kpa!r} kPa is outside 0-{MAX_PRESSURE_KPA:g} kPa")
    return round(kpa / PRESSURE_LSB_KPA)


def interlock_bits(door: bool, clamp: bool, estop: bool, net: bool = True, breech: bool = True) -> int:
    """The interlock register: bit set = closed."""
    closed = {"door": door, "clamp": clamp, "estop": estop, "net": net, "breech": breech}
    return sum(1 << INTERLOCK_BITS[name] for name, is_closed in closed.items() if is_closed)


def status_registers(
    regs: RegisterMap, status: CannonStatus, fault: int = 0, bits: int | None = None
) -> dict[int, int]:
    """Address -> value of the status registers for `status` (`bits` overrides the interlocks)."""
    ilk = status.interlocks
    return {
        regs.state: STATE_VALUES[status.state],
        regs.pressure: pressure_count(min(max(status.pressure_kpa, 0.0), MAX_PRESSURE_KPA)),
        regs.setpoint: pressure_count(status.setpoint_kpa),
        regs.interlocks: interlock_bits(ilk.door, ilk.clamp, ilk.estop) if bits is None else bits,
        regs.shots: status.shots & 0xFFFF,
        regs.fault: fault,
    }


def environment_registers(regs: RegisterMap, env: Environment) -> dict[int, int]:
    """Address -> value of temperature (signed 0.01 degC) and humidity (0.1 %RH)."""
    temp = max(-32768, min(32767, round(env.temperature_c / TEMPERATURE_LSB_C)))
    rh = max(0, min(1000, round(env.humidity_pct / HUMIDITY_LSB_PCT)))
    return {regs.temperature: temp & 0xFFFF, regs.humidity: rh}


# -- decoding (the host's side) ---------------------------------------------------------------


def _at(regs_values: list[int], start: int, address: int) -> int:
    offset = address - start
    if not 0 <= offset < len(regs_values):
        raise ValueError(f"register {address} is not in the {len(regs_values)} read from {start}")
    return regs_values[offset]


def decode_status(regs: RegisterMap, start: int, values: list[int]) -> PlcStatus:
    """The status block read from `start`; ValueError naming a register with an impossible value."""
    code = _at(values, start, regs.state)
    if code not in STATE_CODES:
        raise ValueError(f"state register {regs.state} holds {code}, not a state (0-3)")
    bits = _at(values, start, regs.interlocks)
    if bits & ~ALL_CLOSED & 0xFFFF:
        raise ValueError(f"interlock register {regs.interlocks} holds 0x{bits:04X}: bits above 4 are unused")
    closed = {name: bool(bits >> bit & 1) for name, bit in INTERLOCK_BITS.items()}
    door = all(closed[name] for name in ENCLOSURE)
    status = CannonStatus(
        state=STATE_CODES[code],
        pressure_kpa=round(_at(values, start, regs.pressure) * PRESSURE_LSB_KPA, 1),
        setpoint_kpa=round(_at(values, start, regs.setpoint) * PRESSURE_LSB_KPA, 1),
        interlocks=Interlocks(door=door, clamp=closed["clamp"], estop=closed["estop"]),
        shots=_at(values, start, regs.shots),
    )
    return PlcStatus(status, _at(values, start, regs.fault), bits)


def decode_environment(regs: RegisterMap, start: int, values: list[int]) -> Environment:
    """Temperature and humidity from the environment block read from `start`."""
    raw_t = _at(values, start, regs.temperature)
    temp = (raw_t - 0x10000 if raw_t & 0x8000 else raw_t) * TEMPERATURE_LSB_C
    return Environment(round(temp, 2), round(_at(values, start, regs.humidity) * HUMIDITY_LSB_PCT, 1))


# -- what may happen next ---------------------------------------------------------------------


def _with_fault(plc: PlcStatus, reason: str | None) -> str | None:
    if plc.fault:
        return f"PLC reports fault {plc.fault_name}"
    if reason is not None and reason.startswith("interlock open"):
        return "interlock open: " + ", ".join(plc.open_interlocks())
    return reason


def refuse_plc_arm(plc: PlcStatus) -> str | None:
    """Why ARM must not be written now (a fault, then the state table's refuse_arm), or None."""
    return _with_fault(plc, refuse_arm(plc.status))


def refuse_plc_fire(plc: PlcStatus) -> str | None:
    """Why FIRE must not be written now (a fault, then the state table's refuse_fire), or None."""
    return _with_fault(plc, refuse_fire(plc.status))


def fault_count(simulated_code: str) -> int:
    """A simulated cannon's fault name as the fault register's value."""
    return FAULT_VALUES.get(simulated_code, 0xFF if simulated_code else 0)


# -- frames as recorded -----------------------------------------------------------------------


@dataclass(frozen=True)
class Frame:
    """One Modbus TCP frame (MBAP header + PDU) as recorded in a run's traffic."""

    transaction: int
    unit: int
    function: int
    data: bytes  # the PDU after the function code


def split_frames(stream: bytes) -> tuple[list[Frame], bytes]:
    """The complete MBAP frames at the start of `stream`, and the bytes left over."""
    frames: list[Frame] = []
    while len(stream) >= 8:
        tid, proto, length, unit = struct.unpack(">HHHB", stream[:7])
        if proto != 0 or length < 2:
            raise ValueError(f"not a Modbus TCP frame: protocol {proto}, length {length}")
        end = 6 + length
        if len(stream) < end:
            break
        frames.append(Frame(tid, unit, stream[7], bytes(stream[8:end])))
        stream = stream[end:]
    return frames, stream


def written_command(frame: Frame, regs: RegisterMap) -> str | None:
    """The command a request frame writes (ARM, FIRE, ...), or PSET, or None."""
    if frame.function != 6 or len(frame.data) != 4:
        return None
    address, value = struct.unpack(">HH", frame.data)
    if address == regs.command:
        return COMMAND_NAMES.get(value, f"command {value}")
    return "PSET" if address == regs.setpoint else None
