"""SIGINT and SIGTERM during a run: stop cleanly after the shot in progress, or at once on a second.

The first signal asks the runner to stop before its next step (the shot in progress is finished
and recorded first); the run is then recorded as interrupted and stays resumable. A second signal
raises ForcedStop wherever the runner is: a shot it interrupts is recorded lost (it may have been
fired), never fired again. Further signals are ignored while the interruption is recorded, and
after a stop until the process exits (the CLI's use).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

from protocols.runner import RunControl

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class ForcedStop(KeyboardInterrupt):
    """A second stop signal: the run stops where it is."""


@contextmanager
def stop_on_signals(control: RunControl) -> Iterator[None]:
    """While inside, SIGINT and SIGTERM stop the run `control` steers (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[str] = []

    def on_signal(signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        received.append(name)
        if len(received) == 1:
            control.abort(f"stopped by {name} (the shot in progress was recorded first)")
        elif len(received) == 2:
            raise ForcedStop(f"stopped at once by a second signal ({', '.join(received)})")

    previous = {s: signal.signal(s, on_signal) for s in SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            # once stopped, a late signal must not turn the recorded stop into a traceback on the way out
            signal.signal(s, signal.SIG_IGN if received else handler)
