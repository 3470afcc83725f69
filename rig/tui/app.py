"""The operator's console: a Textual app over rig.certification, rig.session and rig.store."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, ClassVar

from rich.text import Text
from textual import work
from textual.app import App
from textual.binding import Binding, BindingType

from rig.tui.messages import OpenHistory, RunEnded, StartRun
from rig.tui.modals import ConfirmScreen, HelpScreen, TooSmallScreen
from rig.tui.rigs import LOADING, ConsoleSettings, LeftOpen
from rig.tui.setup import SetupScreen

if TYPE_CHECKING:  # the run and history screens load when first opened: a faster start
    from rig.tui.run import RunScreen


class RigConsole(App[None]):
    """Set-up, run and history screens; `?` help and `q` quit everywhere.

    The screens do not open one another: they post rig.tui.messages, handled here.
    """

    TITLE = "Rig console"
    MIN_SIZE = (80, 24)  # below it the screens would cut the rig label, the metric, the prompts
    # textual declares both `ClassVar[...] | None`, which mypy reads as instance variables
    HORIZONTAL_BREAKPOINTS: ClassVar[list[tuple[int, str]]] = [(0, "-narrow"), (120, "-wide")]  # type: ignore[misc]
    VERTICAL_BREAKPOINTS: ClassVar[list[tuple[int, str]]] = [(0, "-short"), (40, "-tall")]  # type: ignore[misc]
    ENABLE_COMMAND_PALETTE = False  # every command has its key; keep the footer for them
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("question_mark,f1", "help", "Help"),
        Binding("q", "quit", "Quit"),
    ]

    def __init__(self, settings: ConsoleSettings) -> None:
        super().__init__()
        self.settings = settings
        self.left_open_runs: dict[str, LeftOpen] = {}  # by run id: what `rig tui` says at exit

    @property
    def left_open(self) -> list[LeftOpen]:
        """The runs this console leaves unfinished (resumable), in the order they stopped."""
        return list(self.left_open_runs.values())

    def on_run_ended(self, message: RunEnded) -> None:
        """A run stopped: remember it while it stays resumable, forget it once it has finished."""
        self._ran(message.left, message.open)

    def _ran(self, left: LeftOpen, still_open: bool) -> None:
        self.left_open_runs.pop(left.run_id, None)
        if still_open and left.run_id:
            self.left_open_runs[left.run_id] = left

    def on_mount(self) -> None:
        self.push_screen(SetupScreen(self.settings))
        self.call_after_refresh(self._check_size)
        self.call_after_refresh(self._warm_up)

    @work(thread=True, group="warm-up", exit_on_error=False)
    def _warm_up(self) -> None:
        """After the first paint, load the run and history screens (and the procedures, the
        session, the physics they use) in the background, so Start does not wait for them."""
        with LOADING:
            import rig.tui.history
            import rig.tui.run  # noqa: F401

    def on_resize(self) -> None:
        self.call_after_refresh(self._check_size)

    def _check_size(self) -> None:
        """Below MIN_SIZE, cover the screen with a notice that says so (and what matters now)."""
        small = self.size.width < self.MIN_SIZE[0] or self.size.height < self.MIN_SIZE[1]
        covered = isinstance(self.screen, TooSmallScreen)
        if small and not covered:
            self.push_screen(TooSmallScreen(self.MIN_SIZE, self.essentials))
        elif not small and covered:
            self.pop_screen()

    def essentials(self) -> Text:
        """What must stay readable at any size: the rig (SIMULATED or not), the prompt, the metric."""
        screen = self.run_screen or next(reversed(self._run_screens()), None)
        if screen is None:
            return Text(self.settings.rigs[0].label, style="bold")
        return screen.essentials()

    def on_open_history(self, message: OpenHistory) -> None:
        """A screen asks for the past runs."""
        with LOADING:
            from rig.tui.history import HistoryScreen

        self.push_screen(HistoryScreen(self.settings, message.rig))

    def on_start_run(self, message: StartRun) -> None:
        """A screen asks for a run (a new one from set-up, or a resumed one from the history)."""
        with LOADING:
            from rig.tui.run import RunScreen
        screen = RunScreen(self.settings, message.job, message.past)
        if message.replace:
            self.switch_screen(screen)
            return
        then = message.then
        self.push_screen(screen, None if then is None else lambda _: then())

    @property
    def run_screen(self) -> RunScreen | None:
        """The run screen whose run is active, if any."""
        return next((s for s in self._run_screens() if s.running), None)

    def _run_screens(self) -> list[RunScreen]:
        """The run screens on the stack, newest last (none before the run screen's module loads)."""
        run = sys.modules.get("rig.tui.run")
        return [] if run is None else [s for s in self.screen_stack if isinstance(s, run.RunScreen)]

    @property
    def run_active(self) -> bool:
        """Whether a certification is running now."""
        return self.run_screen is not None

    def action_help(self) -> None:
        """The keys of every screen."""
        if not isinstance(self.screen, HelpScreen):
            self.push_screen(HelpScreen())

    async def action_quit(self) -> None:
        """Quit; while a run is active, ask first, then stop it (resumable) and wait for it."""
        screen = self.run_screen
        if screen is None:
            self.exit()
            return

        async def stop_then_exit() -> None:
            await screen.finish("the operator quit the console")
            self._ran(*screen.left_open())  # now: its message would come after the exit
            self.exit()

        def confirmed(yes: bool | None) -> None:
            if yes:
                self.notify("stopping the run after the current step...", title="Quit")
                self.run_worker(stop_then_exit(), group="quit")

        self.push_screen(
            ConfirmScreen("A run is active. Stop it (it stays resumable) and quit?", "Quit (y)", "Stay (n)"),
            confirmed,
        )
