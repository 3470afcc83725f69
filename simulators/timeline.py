"""Virtual-time bookkeeping: each device's output queue and the world's scheduled state changes.

Nothing sleeps. A command's consequences are queued at once, each stamped with the virtual time
it happens; the host taking delivery of a message moves the world's clock to that message's time,
and state changes scheduled up to then are applied in order. A later command can still cancel
consequences that lie in the virtual future (VENT cancels the pending READY, DISARM the unread
beam breaks).
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(order=True)
class Entry:
    """One framed message (or an unplug marker) waiting for the host."""

    time_s: float
    order: int
    data: bytes = field(compare=False)
    tag: str | None = field(compare=False, default=None)
    shot: int = field(compare=False, default=0)  # the shot that caused it, 0 if none
    unplug: bool = field(compare=False, default=False)


class OutputQueue:
    """A device's bytes to the host, in virtual-time order (first queued first for equal times)."""

    def __init__(self) -> None:
        self._entries: list[Entry] = []
        self._offset = 0  # bytes of the head entry already delivered
        self._order = itertools.count()

    def push(self, time_s: float, data: bytes, tag: str | None = None, shot: int = 0) -> None:
        """Queue a message for virtual time `time_s`."""
        entry = Entry(time_s, next(self._order), data, tag, shot)
        if not self._entries or entry >= self._entries[-1]:
            self._entries.append(entry)  # the usual case: consequences arrive in time order
        else:
            lo = 1 if self._offset else 0  # never insert before a half-delivered head
            idx = next(i for i in range(lo, len(self._entries)) if entry < self._entries[i])
            self._entries.insert(idx, entry)

    def pending(self) -> int:
        """Bytes the host can read now (up to an unplug marker)."""
        total = 0
        for entry in self._entries:
            if entry.unplug:
                break
            total += len(entry.data)
        return total - self._offset

    def at_unplug(self) -> bool:
        """True if the next thing the host would meet is the unplug."""
        return bool(self._entries) and self._entries[0].unplug

    def take(self, size: int) -> tuple[bytes, float | None]:
        """Up to `size` bytes (all if negative) and the latest virtual time among them."""
        out = bytearray()
        latest: float | None = None
        while self._entries and (size < 0 or len(out) < size) and not self._entries[0].unplug:
            head = self._entries[0]
            want = len(head.data) - self._offset if size < 0 else size - len(out)
            chunk = head.data[self._offset : self._offset + want]
            out += chunk
            latest = head.time_s
            self._offset += len(chunk)
            if self._offset == len(head.data):
                self._entries.pop(0)
                self._offset = 0
        return bytes(out), latest

    def cancel(self, tag: str, after_s: float) -> None:
        """Withdraw undelivered messages tagged `tag` that lie after virtual time `after_s`."""
        keep = [e for i, e in enumerate(self._entries) if not self._cancellable(i, e, tag, after_s)]
        self._entries = keep

    def _cancellable(self, i: int, e: Entry, tag: str, after_s: float) -> bool:
        return e.tag == tag and e.time_s > after_s and not (i == 0 and self._offset)

    def unplug_after(self, shot: int, count: int, fallback_s: float) -> float:
        """Put an unplug marker after the `count`-th message of `shot`; drop all that follows it."""
        mine = [i for i, e in enumerate(self._entries) if e.shot == shot]
        if not mine:
            cut, when = len(self._entries), fallback_s
        elif count == 0:
            cut, when = mine[0], self._entries[mine[0]].time_s
        else:
            last = mine[min(count, len(mine)) - 1]
            cut, when = last + 1, self._entries[last].time_s
        del self._entries[cut:]
        self._entries.append(Entry(when, next(self._order), b"", unplug=True))
        return when

    def discard_due(self, now_s: float) -> None:
        """Drop messages whose time has come (what a real port would already hold)."""
        keep = [e for e in self._entries if e.time_s > now_s or e.unplug]
        if self._entries and keep and keep[0] is not self._entries[0]:
            self._offset = 0
        if not keep:
            self._offset = 0
        self._entries = keep

    def clear(self) -> None:
        """Forget everything queued."""
        self._entries.clear()
        self._offset = 0


@dataclass(order=True)
class _Action:
    time_s: float
    order: int
    apply: Callable[[], None] = field(compare=False)
    tag: str | None = field(compare=False, default=None)
    cancelled: bool = field(compare=False, default=False)


class Schedule:
    """State changes that take effect at a virtual time (the pressure's READY, the grip locking)."""

    def __init__(self) -> None:
        self._heap: list[_Action] = []
        self._order = itertools.count()

    def at(self, time_s: float, apply: Callable[[], None], tag: str | None = None) -> None:
        """Apply `apply()` when the clock reaches `time_s`."""
        heapq.heappush(self._heap, _Action(time_s, next(self._order), apply, tag))

    def cancel(self, tag: str) -> None:
        """Forget pending changes tagged `tag`."""
        for action in self._heap:
            if action.tag == tag:
                action.cancelled = True

    def due(self, until_s: float) -> list[tuple[float, Callable[[], None]]]:
        """Pop the changes due up to `until_s`, in time order."""
        out = []
        while self._heap and self._heap[0].time_s <= until_s:
            action = heapq.heappop(self._heap)
            if not action.cancelled:
                out.append((action.time_s, action.apply))
        return out
