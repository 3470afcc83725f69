"""One opened port and the daemon thread that reads it, until stopped or the port fails.

A transport makes a new `Connection` for every (re)connect, so nothing of an old connection (a
half-read line, a late failure) can leak into the next one.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable
from typing import Protocol

from rig.drivers.traffic import TrafficLog
from rig.drivers.wire import Item, LineDecoder

log = logging.getLogger(__name__)

JOIN_S = 1.0  # how long stop() waits for the reader thread


class SerialLike(Protocol):
    """What a connection needs of a port: pyserial's `Serial` or a test double."""

    timeout: float | None

    @property
    def is_open(self) -> bool: ...
    @property
    def in_waiting(self) -> int: ...
    def read(self, size: int = 1) -> bytes: ...
    def write(self, data: bytes, /) -> int | None: ...
    def close(self) -> None: ...


class Connection:
    """Reads `port` on a daemon thread: logs every chunk, decodes it and hands on each item.

    `on_item(connection, item, t)` gets every decoded item with the chunk's receive time;
    `on_lost(connection, reason)` is called once if reading fails or the thread dies.
    """

    def __init__(
        self,
        name: str,
        port: SerialLike,
        traffic: TrafficLog,
        on_item: Callable[[Connection, Item, float], None],
        on_lost: Callable[[Connection, str], None],
        read_timeout_s: float = 0.05,
    ) -> None:
        self.name, self.port, self.traffic = name, port, traffic
        self._on_item, self._on_lost = on_item, on_lost
        if not getattr(port, "timeout", None):  # a blocking read could never notice stop()
            port.timeout = read_timeout_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"{name}-reader", daemon=True)

    def start(self) -> None:
        """Start reading."""
        self._thread.start()

    def write(self, frame: bytes) -> None:
        """Log then write one frame (logged first, so it precedes its reply in the log)."""
        self.traffic.add("tx", frame)
        self.port.write(frame)

    def stop(self) -> None:
        """Stop the reader thread (waking a read in progress where the port can) and wait for it."""
        self._stop.set()
        cancel = getattr(self.port, "cancel_read", None)  # pyserial's posix and loop ports have it
        if cancel is not None:
            with contextlib.suppress(Exception):
                cancel()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(JOIN_S)
            if self._thread.is_alive():
                log.warning("%s: reader thread did not stop within %g s", self.name, JOIN_S)

    def close(self) -> None:
        """Stop reading and close the port, ignoring errors of a port already gone."""
        self.stop()
        with contextlib.suppress(Exception):
            self.port.close()

    @property
    def reading(self) -> bool:
        """The reader thread is running."""
        return self._thread.is_alive()

    def _run(self) -> None:
        decoder = LineDecoder("host")
        reason = "reader thread ended"
        try:
            while not self._stop.is_set():
                try:
                    data = self.port.read(max(1, self.port.in_waiting))
                except OSError as exc:  # serial.SerialException is an OSError
                    reason = f"read failed: {exc}"
                    return
                if data:
                    t = time.monotonic()
                    self.traffic.add("rx", data, t)
                    for item in decoder.feed(data):
                        self._on_item(self, item, t)
        except Exception as exc:  # a bug must not leave callers waiting: they get DeviceGone
            log.exception("%s: reader thread died", self.name)
            reason = f"reader thread died: {exc!r}"
        finally:
            if not self._stop.is_set():
                self._on_lost(self, reason)
