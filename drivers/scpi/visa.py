"""A VISA line transport (PyVISA, pure-Python `@py` backend): SCPI text lines out and in, recorded.

Every line written and read goes to `on_traffic` as the bytes on the wire ("\\n" included); a line
written is recorded once the write has succeeded (stamped when it was handed over), so a failed
write leaves no bytes in the record that never left. The link is synchronous - a reply is read
only after its write returned - so the record keeps the order of the wire. VISA
failures become the project's errors with one line naming the resource: a timeout DeviceTimeout,
a refused, reset or closed connection DeviceGone. After a timeout the next call reopens the
resource first (a late reply must not be taken for the answer to a later query).
"""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Callable
from typing import Any

import pyvisa
from pyvisa import constants
from pyvisa.errors import VisaIOError

from rig.core.errors import DeviceGone, DeviceTimeout, GarbledReply
from rig.drivers.traffic import Direction, TrafficRecord

TERMINATION = "\n"


# what pyvisa-py needs beyond itself for a resource class (its own messages say so too)
NEEDS = {
    "USB": "USB needs pyusb and the system's libusb: pip install pyusb",
    "GPIB": "GPIB needs linux-gpib or gpib-ctypes and the board's driver",
}


def resource_kind(resource: str) -> str | None:
    """The interface of a VISA resource string (TCPIP, USB, GPIB, ASRL), None if it is not one."""
    head = resource.split("::", 1)[0].upper()
    for kind in ("TCPIP", "USB", "GPIB", "ASRL"):
        if head.startswith(kind) and "::" in resource:
            return kind
    return None


class VisaLink:
    """One VISA resource spoken to in text lines; `write`, `query`, `reconnect`, `close`."""

    def __init__(
        self,
        resource: str,
        *,
        device: str,
        timeout_s: float,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        backend: str = "@py",
    ) -> None:
        self.resource_name = resource
        self.device = device
        self.timeout_s = timeout_s
        self.on_traffic = on_traffic
        self._backend = backend
        self._manager: Any = None
        self._resource: Any = None
        self._stale = False  # a query timed out: its reply may still come, so reopen before the next
        self.closed = False
        self._open()

    def _open(self) -> None:
        kind = resource_kind(self.resource_name)
        if kind is None:
            raise DeviceGone(
                self.device,
                f"{self.resource_name!r} is not a VISA resource string "
                "(e.g. TCPIP0::host::5025::SOCKET, USB0::0x0957::0x1907::SERIAL::INSTR, GPIB0::3::INSTR)",
            )
        try:
            if self._manager is None:
                self._manager = pyvisa.ResourceManager(self._backend)
            self._resource = self._manager.open_resource(
                self.resource_name,
                read_termination=TERMINATION,
                write_termination=TERMINATION,
                timeout=self._ms(self.timeout_s),
                open_timeout=self._ms(self.timeout_s),
            )
        except (VisaIOError, OSError, ValueError, pyvisa.errors.Error) as exc:
            why = " ".join(str(exc).split())  # pyvisa-py's messages for USB and GPIB span lines
            need = NEEDS.get(kind, "")
            raise DeviceGone(
                self.device,
                f"cannot open VISA resource {self.resource_name!r}: {why}" + (f" ({need})" if need else ""),
            ) from None
        sock = self._socket()
        if sock is not None:
            # SCPI is many small lines, most unanswered: without this, Nagle's algorithm holds each
            # line until the previous one is acknowledged (40 ms per command). pyvisa-py 0.8 does not
            # set VI_ATTR_TCPIP_NODELAY itself ("Unknown attribute"), so it is set on its socket.
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._stale = False

    @staticmethod
    def _ms(seconds: float) -> int:
        return max(1, round(seconds * 1000))

    def reconnect(self) -> None:
        """Close and open the resource again (a new connection: the instrument keeps its state)."""
        self._drop()
        self.closed = False
        self._open()

    def close(self) -> None:
        """Close the resource and the manager; a second call does nothing."""
        self._drop()
        if self._manager is not None:
            with contextlib.suppress(Exception):
                self._manager.close()
            self._manager = None
        self.closed = True

    def _drop(self) -> None:
        if self._resource is not None:
            with contextlib.suppress(Exception):
                self._resource.close()
            self._resource = None

    def _record(self, direction: Direction, data: bytes, t_s: float | None = None) -> None:
        if self.on_traffic is not None:
            when = time.monotonic() if t_s is None else t_s
            self.on_traffic(TrafficRecord(t_s=when, direction=direction, data=data))

    def _ready(self) -> Any:
        if self.closed:
            raise DeviceGone(self.device, f"VISA resource {self.resource_name} is closed")
        if self._resource is None or self._stale:
            self.reconnect()
        return self._resource

    def write(self, line: str) -> None:
        """Send one SCPI line; recorded once written (a failed write records nothing)."""
        resource = self._ready()
        data = (line + TERMINATION).encode("ascii")
        started = time.monotonic()
        try:
            resource.write_raw(data)
        except (VisaIOError, OSError) as exc:
            self._resource = None
            raise DeviceGone(self.device, f"{line}: connection to {self.resource_name} lost: {exc}") from None
        self._record("tx", data, started)

    def query(self, line: str, timeout_s: float | None = None) -> str:
        """Send `line` and read one reply line (within `timeout_s`, else the link's timeout)."""
        self.write(line)
        resource = self._resource
        wait = self.timeout_s if timeout_s is None else timeout_s
        try:
            resource.timeout = self._ms(wait)
            data = resource.read_raw()
        except VisaIOError as exc:
            if exc.error_code != constants.StatusCode.error_timeout:
                self._resource = None
                raise DeviceGone(self.device, f"{line}: {self.resource_name}: {exc.description}") from None
            if self._peer_closed():
                self._resource = None
                raise DeviceGone(self.device, f"{line}: {self.resource_name} closed the connection") from None
            self._stale = True
            raise DeviceTimeout(
                self.device, f"no reply to {line} from {self.resource_name} within {wait:g} s"
            ) from None
        except OSError as exc:
            self._resource = None
            raise DeviceGone(self.device, f"{line}: connection to {self.resource_name} lost: {exc}") from None
        finally:
            if self._resource is not None:
                with contextlib.suppress(Exception):
                    self._resource.timeout = self._ms(self.timeout_s)
        self._record("rx", bytes(data))
        try:
            return bytes(data).decode("ascii").rstrip("\r\n")
        except UnicodeDecodeError:
            raise GarbledReply(
                self.device, f"reply to {line} holds a byte that is not ASCII: {bytes(data)[:60]!r}"
            ) from None

    def _peer_closed(self) -> bool:
        """True if a raw TCPIP socket resource was closed by the instrument (pyvisa-py reads an
        end of stream as silence, so a dropped connection first looks like a timeout)."""
        sock = self._socket()
        if sock is None:
            return False
        try:
            return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except BlockingIOError:
            return False
        except OSError:
            return True

    def _socket(self) -> socket.socket | None:
        """The raw socket under a pyvisa-py TCPIP SOCKET resource, if that is what is open."""
        try:
            sock = self._manager.visalib.sessions[self._resource.session].interface
        except Exception:
            return None
        return sock if isinstance(sock, socket.socket) else None
