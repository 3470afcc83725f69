"""A serial port in front of a TCP server: a pty whose bytes go to and come from one TCP connection.

A simulated instrument that speaks its serial protocol on TCP (pymodbus's server with the RTU
framer, say) becomes a device path a driver opens with pyserial as it would a USB adapter. The pty
is raw (no echo, no line editing, every byte passed). Faults for tests: `garble_next()` flips one
bit of the next reply, `inject(data)` puts bytes on the line, `unplug()` closes the pty as a pulled
adapter would (its path is gone).
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import tty

CHUNK = 4096
POLL_S = 0.05  # how often the bridge looks at its stop flag


class PtyBridge:
    """One pty bridged to a TCP connection to host:port; `path` is the serial device."""

    def __init__(self, host: str, port: int) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.sock = socket.create_connection((host, port), timeout=10.0)
        self.sock.settimeout(None)  # select says when it is readable; sendall may wait
        self._garble = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"pty-bridge-{port}", daemon=True)

    def start(self) -> str:
        """Start passing bytes; the device path."""
        self._thread.start()
        return self.path

    def garble_next(self, times: int = 1) -> None:
        """Flip the lowest bit of one byte in the middle of each of the next `times` replies."""
        self._garble += times

    def inject(self, data: bytes) -> None:
        """Put bytes on the line toward the driver now (noise, a late reply)."""
        os.write(self.master, data)

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self.master, self.sock], [], [], POLL_S)
                if self.master in ready:
                    data = os.read(self.master, CHUNK)
                    if data:
                        self.sock.sendall(data)
                if self.sock in ready:
                    data = self.sock.recv(CHUNK)
                    if not data:
                        return  # the server went away: the line goes quiet
                    os.write(self.master, self._maybe_garble(data))
        except OSError:
            return  # closed under us (unplug/close)

    def _maybe_garble(self, data: bytes) -> bytes:
        if self._garble <= 0 or not data:
            return data
        self._garble -= 1
        i = len(data) // 2
        return data[:i] + bytes([data[i] ^ 0x01]) + data[i + 1 :]

    def unplug(self) -> None:
        """The adapter is pulled: the pty and the connection are closed, the path disappears."""
        self.close()

    def close(self) -> None:
        """Stop and close everything (idempotent)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        self.master = self.slave = -1
        with contextlib.suppress(OSError):
            self.sock.close()
