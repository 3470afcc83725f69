"""SIGINT and SIGTERM during a run: stop cleanly after the shot in progress, or at once on a second.

The first signal asks the runner to stop before its next step (the shot in progress is finished
and recorded first); the run is then recorded as interrupted and stays resumable. A second signal
raises ForcedStop wherever the runner is: a shot it interrupts is recorded lost (it may have been
fired), never fired again. Signals are ignored once the runner has stopped and its outcome is
being recorded (RunControl.settled), and, once a run has ended or been stopped, until the process
exits (the CLI's use): a late signal must not change the exit status the recorded outcome gives
(3 for an interruption, the verdict's code), nor end the process by the signal (130/143).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

from rig.protocols.control import RunControl

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class ForcedStop(KeyboardInterrupt):
    """A second stop signal: the run stops where it is."""


class SignalStop:
    """The signal handler: how many stop signals came, for the run `control` steers."""

    def __init__(self, control: RunControl) -> None:
        self.control = control
        self.received: list[str] = []

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        """First signal: stop after the shot in progress; second: stop at once; later ones: ignored."""
        name = signal.Signals(signum).name
        self.received.append(name)
        if self.control.settled:
            return  # the outcome is being recorded: a late signal must not tear that up
        if len(self.received) == 1:
            self.control.abort(f"stopped by {name} (the shot in progress was recorded first)")
        elif len(self.received) == 2:
            raise ForcedStop(f"stopped at once by a second signal ({', '.join(self.received)})")


@contextmanager
def stop_on_signals(control: RunControl, until_exit: bool = True) -> Iterator[SignalStop]:
    """While inside, SIGINT and SIGTERM stop the run `control` steers (main thread only).

    On the way out, once a signal came or a run ended (`control.settled`), they are ignored from
    then on (the process is reporting a recorded outcome and exiting); `until_exit=False`: only
    after a signal (a command that goes on to other work once its runs are done)."""
    stop = SignalStop(control)
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    previous = {s: signal.signal(s, stop.on_signal) for s in SIGNALS}
    try:
        yield stop
    finally:
        ended = bool(stop.received) or (until_exit and control.settled)
        for s, handler in previous.items():
            signal.signal(s, signal.SIG_IGN if ended else handler)
