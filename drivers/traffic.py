"""The raw traffic log: every byte a driver sent or received, in order, with its time.

Nothing is lost: a store can take the records as they come (the hook) or in batches (`take`),
and a recorded stream can be fed back through the codecs to re-derive results.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

log = logging.getLogger(__name__)

Direction = Literal["tx", "rx"]


@dataclass(frozen=True)
class TrafficRecord:
    """Bytes that went out ('tx') or came in ('rx'), stamped with time.monotonic()."""

    t_s: float
    direction: Direction
    data: bytes


class TrafficLog:
    """Every byte in and out, in order; thread-safe, with an optional hook called per record."""

    def __init__(self, on_record: Callable[[TrafficRecord], None] | None = None) -> None:
        self._records: list[TrafficRecord] = []
        self._lock = threading.Lock()
        self.on_record = on_record

    def add(self, direction: Direction, data: bytes, t_s: float | None = None) -> TrafficRecord:
        """Append one record (stamped now unless `t_s` is given) and pass it to the hook."""
        rec = TrafficRecord(time.monotonic() if t_s is None else t_s, direction, bytes(data))
        with self._lock:
            self._records.append(rec)
        if self.on_record is not None:
            try:
                self.on_record(rec)
            except Exception:  # a failing listener must not stop the traffic
                log.exception("traffic hook failed")
        return rec

    def records(self) -> list[TrafficRecord]:
        """A copy of every record so far."""
        with self._lock:
            return list(self._records)

    def take(self) -> list[TrafficRecord]:
        """Hand over the records so far and forget them (for a store that persists them)."""
        with self._lock:
            out, self._records = self._records, []
        return out

    def data(self, direction: Direction) -> bytes:
        """All bytes kept in one direction, concatenated."""
        with self._lock:
            return b"".join(r.data for r in self._records if r.direction == direction)

    def __len__(self) -> int:
        with self._lock:
            return len(self._records)
