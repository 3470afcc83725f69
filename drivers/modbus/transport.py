"""Modbus TCP or RTU to one unit of a PLC, on pymodbus's sync clients, recording every frame.

The bytes recorded are the wire's own: each `send` and each `recv` of the client goes through
`on_traffic` (TCP: MBAP header + PDU; RTU: unit + PDU + CRC, bytes left over before a request too),
in order, as the line protocol's bytes are recorded. Requests are never retried (a write that
reached the PLC must not reach it twice); the unit id is always given and never 0 (broadcast).
Failures become the project's errors in one line naming the unit, the function and the address.

RTU goes over a serial port: a device path (`/dev/ttyUSB0`, `COM3`) or a pyserial URL
(`socket://host:port` for a serial device server passing RTU frames through, `rfc2217://`).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ExceptionResponse, ModbusPDU

from rig.core.errors import DeviceGone, DeviceRefused, DeviceTimeout, GarbledReply
from rig.drivers.modbus.plc_codec import EXCEPTION_NAMES, FUNCTION_NAMES, check_unit
from rig.drivers.traffic import TrafficRecord
from rig.drivers.transport import open_port

# pymodbus logs what it also raises; without a handler Python would print it to stderr
logging.getLogger("pymodbus").addHandler(logging.NullHandler())

DEFAULT_PORT = 502
TRANSPORTS = ("tcp", "rtu")
BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)


@dataclass(frozen=True)
class SerialLine:
    """An RTU line's settings. The Modbus serial-line spec's default is 19200 baud, 8 data bits,
    even parity, 1 stop bit (confirmed: Modbus over Serial Line V1.02, 2.5.1); a PLC may be set
    otherwise, so each is an option."""

    baud: int = 19200
    parity: str = "E"
    stopbits: int = 1

    def __post_init__(self) -> None:
        if self.baud not in BAUDS:
            raise ValueError(f"baud {self.baud} is not a serial rate ({', '.join(map(str, BAUDS))})")
        if self.parity not in ("E", "O", "N"):
            raise ValueError(f"parity {self.parity!r} must be 'E' (even), 'O' (odd) or 'N' (none)")
        if self.stopbits not in (1, 2):
            raise ValueError(f"stopbits {self.stopbits} must be 1 or 2")


LINE_OPTIONS = tuple(f.name for f in fields(SerialLine))  # the driver's RTU-only options


def parse_address(address: str) -> tuple[str, int]:
    """(host, port) of `host:port` or `tcp://host:port` (port 502 if left out); ValueError if bad."""
    text = address.removeprefix("tcp://")
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(DEFAULT_PORT)
    host = host.strip("[]")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"address {address!r} is not host:port (Modbus TCP)")
    return host, int(port)


class _Records:
    """Before a pymodbus client in the bases: its `send` and `recv` bytes are passed to `_record`."""

    _record: Callable[[str, bytes], None]

    def send(self, request: bytes, addr: tuple[Any, ...] | None = None) -> int:
        """Send and record a frame."""
        sent: int = super().send(request, addr)  # type: ignore[misc]
        if request:
            self._record("tx", bytes(request[:sent]))
        return sent

    def recv(self, size: int | None) -> bytes:
        """Receive and record what the wire gave."""
        data: bytes = super().recv(size)  # type: ignore[misc]
        if data:
            self._record("rx", bytes(data))
        return data


class _RecordingClient(_Records, ModbusTcpClient):
    """pymodbus's TCP client, with the socket's bytes passed to `record` as they go and come."""

    def __init__(self, host: str, port: int, timeout_s: float, record: Callable[[str, bytes], None]) -> None:
        self._record = record
        super().__init__(host, port=port, timeout=timeout_s, retries=0, framer=FramerType.SOCKET)


class _RecordingSerialClient(_Records, ModbusSerialClient):
    """pymodbus's RTU client, with the port's bytes passed to `record` as they go and come; bytes
    left on the line before a request (a late reply, noise) are read and recorded, not dropped."""

    def __init__(
        self, port: str, line: SerialLine, timeout_s: float, record: Callable[[str, bytes], None]
    ) -> None:
        self._record = record
        super().__init__(
            port,
            framer=FramerType.RTU,
            baudrate=line.baud,
            bytesize=8,
            parity=line.parity,
            stopbits=line.stopbits,
            timeout=timeout_s,
            retries=0,
        )

    def connect(self) -> bool:
        """Open the port as pymodbus does, keeping why it failed (`failure`) instead of logging it."""
        if self.socket:
            return True
        self.failure = ""
        params = self.comm_params
        port: Any = None
        try:
            port = open_port(
                str(params.host),
                baudrate=int(params.baudrate or 19200),
                timeout=float(params.timeout_connect or 1.0),
                write_timeout=float(params.timeout_connect or 1.0),
                parity=str(params.parity),
                stopbits=int(params.stopbits or 1),
                exclusive=True,
            )
            port.inter_byte_timeout = self.inter_byte_timeout
            self.socket = port
        except DeviceGone as exc:
            self.failure = str(exc.__cause__ or exc)
        except Exception as exc:  # a setting the port refuses (termios.error is no OSError)
            self.failure = (
                f"the port refuses its settings: {' '.join(str(exc).split()) or type(exc).__name__}"
            )
            if port is not None:
                with contextlib.suppress(Exception):
                    port.close()
        return self.socket is not None

    def send(self, request: bytes, addr: tuple[Any, ...] | None = None) -> int:
        """Send and record a frame (first recording what was still waiting on the line)."""
        if self.socket is not None and request:
            try:
                waiting = int(self.socket.in_waiting)
                stale = self.socket.read(waiting) if waiting else b""
            except OSError:
                stale = b""  # super().send meets the same failure and says so
            if stale:
                self._record("rx", bytes(stale))
        return super().send(request, addr)


class ModbusTransport:
    """Requests to one unit over Modbus TCP (`address` host:port) or RTU (`serial`: the line's
    settings, `address` a serial port); thread-safe; every frame recorded."""

    def __init__(
        self,
        name: str,
        address: str,
        unit: int,
        *,
        timeout_s: float = 1.0,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        serial: SerialLine | None = None,
    ) -> None:
        self.name = name
        self.unit = check_unit(unit)
        self.on_traffic = on_traffic
        self._lock = threading.Lock()
        self._rx_since_request = 0
        self.client: ModbusTcpClient | ModbusSerialClient
        if serial is None:
            self.host, self.port = parse_address(address)
            self.wire = f"Modbus TCP {self.host}:{self.port}"
            self.client = _RecordingClient(self.host, self.port, timeout_s, self._record)
        else:
            if not address:
                raise ValueError("a Modbus RTU address is a serial port (a device path or a pyserial URL)")
            self.host, self.port = address, 0
            self.wire = f"Modbus RTU {address} ({serial.baud} 8{serial.parity}{serial.stopbits})"
            self.client = _RecordingSerialClient(address, serial, timeout_s, self._record)
        if not self.client.connect():
            why = getattr(self.client, "failure", "")
            raise DeviceGone(
                name, f"cannot connect to {self.wire} (unit {self.unit})" + (f": {why}" if why else "")
            )

    def _close_client(self) -> None:
        self.client.close()  # type: ignore[no-untyped-call]  # pymodbus leaves close() unannotated

    def _record(self, direction: str, data: bytes) -> None:
        if (
            direction == "tx"
        ):  # bytes read before the request went out (noise, a late reply) are not its reply
            self._rx_since_request = 0
        else:
            self._rx_since_request += len(data)
        if self.on_traffic is not None:
            self.on_traffic(TrafficRecord(t_s=time.monotonic(), direction=direction, data=data))  # type: ignore[arg-type]

    def read_holding(self, address: int, count: int) -> list[int]:
        """Read `count` holding registers from `address` (function 3)."""
        response = self._call(
            3, address, lambda: self.client.read_holding_registers(address, count=count, device_id=self.unit)
        )
        registers = list(getattr(response, "registers", []))
        if len(registers) != count:
            raise GarbledReply(
                self.name, f"{self._where(3, address)}: {len(registers)} registers, not {count}"
            )
        return registers

    def write_register(self, address: int, value: int) -> None:
        """Write one holding register (function 6)."""
        self._call(6, address, lambda: self.client.write_register(address, value, device_id=self.unit))

    def write_registers(self, address: int, values: list[int]) -> None:
        """Write consecutive holding registers in one request (function 16)."""
        self._call(16, address, lambda: self.client.write_registers(address, values, device_id=self.unit))

    def device_identification(self, read_code: int = 3) -> dict[int, bytes]:
        """The objects of Read Device Identification (function 43/14): id -> bytes."""
        response = self._call(
            43,
            0,
            lambda: self.client.read_device_information(
                read_code=read_code, object_id=0, device_id=self.unit
            ),
        )
        info = getattr(response, "information", None)
        if not isinstance(info, dict):
            raise GarbledReply(self.name, f"{self._where(43, 0)}: no objects in the reply")
        return {int(k): v if isinstance(v, bytes) else str(v).encode() for k, v in info.items()}

    def _call(self, function: int, address: int, request: Callable[[], ModbusPDU]) -> ModbusPDU:
        where = self._where(function, address)
        with self._lock:
            self._rx_since_request = 0
            try:
                response = request()
            except ConnectionException as exc:
                self._close_client()
                raise DeviceGone(self.name, f"{where}: connection lost ({_why(exc)})") from None
            except ModbusIOException as exc:
                if not self.client.connected:
                    raise DeviceGone(self.name, f"{where}: connection lost ({_why(exc)})") from None
                if self._rx_since_request:  # bytes came, but no frame of this unit with a good check
                    raise GarbledReply(
                        self.name,
                        f"{where}: {self._rx_since_request} bytes came back but no valid reply frame "
                        "(bad CRC, another unit or a cut frame)",
                    ) from None
                raise DeviceTimeout(self.name, f"{where}: no reply ({_why(exc)})") from None
            except ModbusException as exc:
                raise GarbledReply(self.name, f"{where}: {_why(exc)}") from None
            except OSError as exc:
                self._close_client()
                raise DeviceGone(self.name, f"{where}: {exc}") from None
        if isinstance(response, ExceptionResponse) or response.isError():
            code = int(getattr(response, "exception_code", 0))
            raise DeviceRefused(
                self.name, where, f"exception {code}", EXCEPTION_NAMES.get(code, "(unknown code)")
            )
        return response

    def _where(self, function: int, address: int) -> str:
        what = FUNCTION_NAMES.get(function, f"function {function}")
        at = "" if function == 43 else f" at {address}"
        return f"unit {self.unit} {what} (function {function}){at}"

    def close(self) -> None:
        """Close the connection (a later request would open it again)."""
        with self._lock:
            self._close_client()


def _why(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 160 else text[:157] + "..."
