"""Where a transport keeps the events its device sends until someone waits for them.

Events are kept per name (bounded, oldest dropped first; they stay in the traffic log) and also
copied to one `all_events` queue for listeners that want everything. A waiter takes the oldest
kept event of the names it asks for, so an event that arrives before its waiter is not missed.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from rig.drivers.wire import Event

EVENT_BACKLOG = 1024  # per event name

EventFilter = Callable[[Event], bool]


@dataclass(frozen=True)
class ReceivedEvent:
    """An event with the host's receive time (time.monotonic() s) and its arrival number."""

    t_s: float
    event: Event
    index: int


class EventInbox:
    """Per-name event boxes with blocking, deadline-bound takes; thread-safe."""

    def __init__(self, backlog: int = EVENT_BACKLOG) -> None:
        self._cv = threading.Condition()
        self._boxes: dict[str, deque[ReceivedEvent]] = {}
        self._count = 0
        self._backlog = backlog
        self.all_events: queue.Queue[ReceivedEvent] = queue.Queue(maxsize=backlog)

    def put(self, event: Event, t_s: float) -> ReceivedEvent:
        """Keep one event received at `t_s` and wake the waiters."""
        with self._cv:
            self._count += 1
            rec = ReceivedEvent(t_s, event, self._count)
            self._boxes.setdefault(event.name, deque(maxlen=self._backlog)).append(rec)
            self._cv.notify_all()
        if self.all_events.full():  # keep the newest: drop the oldest
            with contextlib.suppress(queue.Empty):
                self.all_events.get_nowait()
        with contextlib.suppress(queue.Full):
            self.all_events.put_nowait(rec)
        return rec

    def wake(self) -> None:
        """Make every waiter look again (e.g. its port has gone)."""
        with self._cv:
            self._cv.notify_all()

    def take(
        self,
        names: str | Iterable[str],
        timeout_s: float,
        predicate: EventFilter | None = None,
        check: Callable[[], None] = lambda: None,
    ) -> ReceivedEvent | None:
        """The oldest kept event of `names` passing `predicate` (those failing it are discarded),
        waiting up to `timeout_s`; None at the deadline. `check` may raise to end the wait early;
        a kept event is still handed out first."""
        wanted = (names,) if isinstance(names, str) else tuple(names)
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while True:
                found = self._pop(wanted, predicate)
                if found is not None:
                    return found
                check()
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._cv.wait(remaining)

    def clear(self, names: str | Iterable[str] | None = None) -> int:
        """Forget kept events (of `names`, or all); returns how many."""
        with self._cv:
            keys = list(self._boxes) if names is None else [names] if isinstance(names, str) else names
            return sum(len(self._boxes.pop(k, ())) for k in keys)

    def _pop(self, names: tuple[str, ...], predicate: EventFilter | None) -> ReceivedEvent | None:
        best: deque[ReceivedEvent] | None = None
        for name in names:
            box = self._boxes.get(name)
            while box:
                try:
                    ok = predicate is None or predicate(box[0].event)
                except Exception:
                    box.popleft()  # consumed: it would only raise again for the next waiter
                    raise
                if ok:
                    break
                box.popleft()
            if box and (best is None or box[0].index < best[0].index):
                best = box
        return best.popleft() if best else None
