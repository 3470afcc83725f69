"""Modbus TCP to one unit of a PLC, on pymodbus's sync client, recording every frame on the wire.

The bytes recorded are the socket's own: each `send` and each `recv` of the client goes through
`on_traffic` (MBAP header + PDU), in order, as the line protocol's bytes are recorded. Requests are
never retried (a write that reached the PLC must not reach it twice); the unit id is always given
and never 0 (broadcast). Failures become the project's errors in one line naming the unit, the
function and the address.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from pymodbus import FramerType
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ExceptionResponse, ModbusPDU

from rig.core.errors import DeviceGone, DeviceRefused, DeviceTimeout, GarbledReply
from rig.drivers.modbus.plc_codec import EXCEPTION_NAMES, FUNCTION_NAMES, check_unit
from rig.drivers.traffic import TrafficRecord

# pymodbus logs what it also raises; without a handler Python would print it to stderr
logging.getLogger("pymodbus").addHandler(logging.NullHandler())

DEFAULT_PORT = 502


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


class _RecordingClient(ModbusTcpClient):
    """pymodbus's TCP client, with the socket's bytes passed to `record` as they go and come."""

    def __init__(self, host: str, port: int, timeout_s: float, record: Callable[[str, bytes], None]) -> None:
        self._record = record
        super().__init__(host, port=port, timeout=timeout_s, retries=0, framer=FramerType.SOCKET)

    def send(self, request: bytes, addr: tuple[Any, ...] | None = None) -> int:
        """Send and record a frame."""
        sent = super().send(request, addr)
        if request:
            self._record("tx", bytes(request[:sent]))
        return sent

    def recv(self, size: int | None) -> bytes:
        """Receive and record what the socket gave."""
        data = super().recv(size)
        if data:
            self._record("rx", bytes(data))
        return data


class ModbusTransport:
    """Requests to one unit over Modbus TCP; thread-safe; every frame recorded."""

    def __init__(
        self,
        name: str,
        address: str,
        unit: int,
        *,
        timeout_s: float = 1.0,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
    ) -> None:
        self.name = name
        self.unit = check_unit(unit)
        self.host, self.port = parse_address(address)
        self.on_traffic = on_traffic
        self._lock = threading.Lock()
        self.client = _RecordingClient(self.host, self.port, timeout_s, self._record)
        if not self.client.connect():
            raise DeviceGone(name, f"cannot connect to Modbus TCP {self.host}:{self.port} (unit {self.unit})")

    def _record(self, direction: str, data: bytes) -> None:
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
            try:
                response = request()
            except ConnectionException as exc:
                self.client.close()
                raise DeviceGone(self.name, f"{where}: connection lost ({_why(exc)})") from None
            except ModbusIOException as exc:
                if not self.client.connected:
                    raise DeviceGone(self.name, f"{where}: connection lost ({_why(exc)})") from None
                raise DeviceTimeout(self.name, f"{where}: no reply ({_why(exc)})") from None
            except ModbusException as exc:
                raise GarbledReply(self.name, f"{where}: {_why(exc)}") from None
            except OSError as exc:
                self.client.close()
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
            self.client.close()


def _why(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 160 else text[:157] + "..."
