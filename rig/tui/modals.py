"""Modal screens: a yes/no confirmation and the help overlay."""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Static

HELP = """\
[b]Set-up[/b]  the bat file field takes the keys first: a path, Enter loads it
  Tab / Shift+Tab  move between fields         Esc  leave a field
  s (Enter on Start)  start the run   r  read the devices again   h  history
[b]Run[/b]
  f  fire the waiting shot (the key is the confirmation); off (f says why)
     while an interlock is open, the cannon's status is unknown or paused
  Enter  the answer that needs no thought: the ring passes, accept the
     valid shot; never fires (\\[console] one_key: also the rings after)
  y / n  answer one prompt; n on a ring check asks first (it fails the bat)
  p  pause (PAUSED leads the prompt line) / go on   a  abort (resumable)
  r  resume   b  back once ended
[b]History[/b]  Up / Down  choose a run   r  resume it   Esc  back
  PgDn / PgUp  scroll the run's report (a certificate takes a moment)
[b]Anywhere[/b]
  ?  this help (Esc closes it)    q  quit (asks first during a run)
Needs 80x24; from 120x40 the run shows plots, the budget and the traffic."""


class ConfirmScreen(ModalScreen[bool]):
    """Ask a yes/no question; y confirms, n or Esc cancels. Focus starts on the safe answer."""

    DEFAULT_CSS = """
    ConfirmScreen { align: center middle; }
    ConfirmScreen > Vertical {
        width: 60; height: auto; border: thick $warning; background: $surface; padding: 1 2;
    }
    ConfirmScreen Horizontal { height: auto; align-horizontal: center; margin-top: 1; }
    ConfirmScreen Button { margin: 0 2; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("y", "answer(True)", "Yes"),
        Binding("n,escape", "answer(False)", "No"),
    ]

    def __init__(self, question: str, yes: str = "Yes (y)", no: str = "No (n)") -> None:
        super().__init__()
        self.question, self.yes, self.no = question, yes, no

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Static(self.question, id="question")
            with Horizontal():
                yield Button(self.yes, variant="error", id="yes")
                yield Button(self.no, variant="primary", id="no")

    def on_mount(self) -> None:
        self.query_one("#no", Button).focus()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        self.dismiss(event.button.id == "yes")

    def action_answer(self, value: bool) -> None:
        """Close with the answer."""
        self.dismiss(value)


class HelpScreen(ModalScreen[None]):
    """Every key of every screen, over the current screen."""

    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > Static {
        width: 80; height: auto; max-height: 22; border: round $accent; background: $surface;
        padding: 0 1;
    }
    """
    BINDINGS: ClassVar[list[BindingType]] = [Binding("escape,question_mark,q,f1", "close", "Close")]

    def compose(self) -> ComposeResult:
        yield Static(HELP, id="help")

    def on_mount(self) -> None:
        self.query_one("#help", Static).border_title = "Operator console: keys"

    def action_close(self) -> None:
        """Back to the screen below."""
        self.dismiss(None)


class TooSmallScreen(ModalScreen[None]):
    """Covers everything while the terminal is smaller than the console needs; the run goes on.

    The keys of the screens below are off meanwhile (no fire without the full picture); it shows
    the rig, the prompt and the metric, refreshed, and closes itself when the terminal grows.
    """

    BINDINGS: ClassVar[list[BindingType]] = [Binding("q", "app.quit", "Quit")]  # as the notice says

    DEFAULT_CSS = """
    TooSmallScreen { background: $surface; padding: 0 1; }
    TooSmallScreen #need { text-style: bold; color: $warning; height: auto; }
    TooSmallScreen #essentials { height: auto; margin-top: 1; }
    """

    def __init__(self, need: tuple[int, int], essentials: Callable[[], Text]) -> None:
        super().__init__()
        self.need, self.essentials = need, essentials

    def compose(self) -> ComposeResult:
        yield Static(id="need")
        yield Static(id="essentials")

    def on_mount(self) -> None:
        self.show()
        self.set_interval(0.25, self.show)

    def show(self) -> None:
        """Say how big the terminal is and must be; then what matters now."""
        w, h = self.app.size
        if w >= self.need[0] and h >= self.need[1]:  # grown while another screen was on top
            if self.is_current:
                self.dismiss(None)
            return
        need = f"The console needs at least {self.need[0]}x{self.need[1]}; this terminal is {w}x{h}. "
        self.query_one("#need", Static).update(need + "Enlarge it: the keys are off until then (q quits).")
        self.query_one("#essentials", Static).update(self.essentials())
