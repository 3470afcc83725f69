"""What the console's screens ask of the app, as Textual messages (they bubble from a screen to it).

A screen never imports another screen: it posts one of these and the app, which knows every
screen, opens the one asked for. So set-up, run and history stay independent modules.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from textual.message import Message

if TYPE_CHECKING:
    from rig.core.events import RunEvent
    from rig.tui.rigs import LeftOpen, RigChoice, RunJob


class OpenHistory(Message):
    """Show the past runs over the current screen (`rig`: the rig a resumed run would use)."""

    def __init__(self, rig: RigChoice | None = None) -> None:
        super().__init__()
        self.rig = rig


class RunEnded(Message):
    """A run screen's run stopped: finished (`open` False), or left resumable with `reason`."""

    def __init__(self, left: LeftOpen, open_: bool) -> None:
        super().__init__()
        self.left, self.open = left, open_


class StartRun(Message):
    """Open the run screen for `job` (its recorded `past` when resuming).

    replace: instead of the asking screen (the history), else over it; `then` runs when the run
    screen closes.
    """

    def __init__(
        self,
        job: RunJob,
        past: Sequence[RunEvent] = (),
        replace: bool = False,
        then: Callable[[], None] | None = None,
    ) -> None:
        super().__init__()
        self.job, self.past, self.replace, self.then = job, list(past), replace, then
