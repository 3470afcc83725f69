"""Run screen: the certification live, with the operator's keys (fire, answer, pause, abort).

The run itself is `rig.certification.certify` in a thread worker. Its events and the operator's
prompts come back through `app.call_from_thread`; the keys only send commands (RunControl, the
operator's answers). Nothing here touches a device.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import replace
from typing import Any, ClassVar

from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Grid, Horizontal
from textual.screen import Screen
from textual.widgets import Header, RichLog, Static
from textual.worker import Worker

from rig.certification import Outcome
from rig.core import events as ev
from rig.core.events import RunEvent
from rig.core.run_phase import CLOSED, RunPhase
from rig.protocols.control import RunControl
from rig.tui import render, situation
from rig.tui.jobs import JobResult, predict, run_job
from rig.tui.keybar import KeyBar
from rig.tui.live import LiveRun
from rig.tui.messages import RunEnded
from rig.tui.operator import CannonRead, ConsoleOperator, GatesRead, Notice, PromptPending
from rig.tui.rigs import ConsoleSettings, LeftOpen, RunJob
from rig.tui.run_keys import RunKeys
from rig.tui.situation import Situation

log = logging.getLogger(__name__)
WIDE = ("scan-plot", "hits-plot", "budget")
SIZED_BY_TEXT = ("prompt", "message")  # height: auto in the CSS below


class RunScreen(RunKeys, Screen[None]):
    """One certification run, live."""

    DEFAULT_CSS = """
    RunScreen #title { height: 1; padding: 0 1; background: $boost; text-style: bold; }
    RunScreen #panels { grid-size: 2 2; grid-columns: 38 1fr; grid-rows: 6 6; height: 12; }
    RunScreen .box { border: round $primary; padding: 0 1; height: 6; }
    RunScreen #wide { display: none; height: 12; }
    RunScreen #wide .box { width: 1fr; height: 12; }
    RunScreen #prompt { height: auto; max-height: 4; padding: 0 1; background: $warning 30%; }
    RunScreen #message { height: auto; max-height: 4; padding: 0 1; }
    RunScreen #bottom { height: 1fr; min-height: 3; }
    RunScreen #log { height: 1fr; width: 1fr; border: round $primary-darken-2; padding: 0 1; }
    RunScreen #traffic { display: none; height: 1fr; width: 1fr; padding: 0 1; }
    RunScreen.-wide.-tall #wide { display: block; }
    RunScreen.-wide.-tall #traffic { display: block; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("f", "fire", "Fire"),
        Binding("f", "fire_off", "Fire", show=False),  # when the shot may not be fired: says why
        Binding("enter", "quick", "OK"),
        Binding("y", "answer(True)", "Yes"),
        Binding("n", "answer(False)", "No"),
        Binding("p", "pause", "Pause"),
        Binding("p", "go_on", "Go on"),  # offered instead of Pause while paused
        Binding("a", "abort", "Abort"),
        Binding("r", "resume", "Resume"),
        Binding("b", "back", "Back"),
        Binding("h", "history", "History"),
    ]

    def __init__(self, settings: ConsoleSettings, job: RunJob, past: list[RunEvent] | None = None) -> None:
        super().__init__()
        self.settings, self.job = settings, job
        self.live = LiveRun()
        self.live.set_procedure(job.procedure)
        for event in past or []:  # a resumed run shows its scan and hits from the start
            self.live.apply(event)
        self.running = False
        self.outcome: Outcome | None = None
        self.failure = ""
        self._closing = False
        self._logged = 0
        self._keys_state: tuple[object, ...] = ()
        self._shown: dict[str, Text] = {}  # each panel's text as last drawn
        self.control = RunControl()
        self.operator = ConsoleOperator(self._notice, poll_s=settings.poll_s)
        self._worker: Worker[None] | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(self._title(), id="title")  # the rig first: SIMULATED is never cut off
        with Grid(id="panels"):
            for name in ("cannon", "shot", "gates", "progress"):
                yield Static(id=name, classes="box")
        with Horizontal(id="wide"):  # shown from 120x40 on
            for name in WIDE:
                yield Static(id=name, classes="box")
        yield Static(id="prompt")
        yield Static(id="message")
        with Horizontal(id="bottom"):
            yield RichLog(id="log", wrap=True, markup=False, max_lines=500)
            yield Static(id="traffic", classes="box")
        yield KeyBar()  # not the Footer: this screen's keys change with every prompt

    def on_mount(self) -> None:
        self.sub_title = "run"
        titles = {"cannon": "Cannon", "shot": "Live shot", "gates": "Gates", "progress": "Scan and hits"}
        titles |= {"scan-plot": "Location scan", "hits-plot": "Valid hits", "budget": "Uncertainty budget"}
        titles["traffic"] = "Device traffic (> sent, < received)"
        for name, title in titles.items():
            self.query_one(f"#{name}", Static).border_title = title
        self.query_one("#log", RichLog).border_title = "Log"
        self.start()

    # -- the worker ---------------------------------------------------------------------------
    def start(self) -> None:
        """Start (or resume) the run in a thread worker."""
        self.running, self.failure, self.outcome = True, "", None
        self.control = RunControl()
        self.operator = ConsoleOperator(self._notice, poll_s=self.settings.poll_s)
        self.live.interrupted, self.live.cannon_note = "", ""
        self._predict_soon()
        self._worker = self._certify(self.job)
        self.refresh_view()

    @work(thread=True, exclusive=True, group="certify", exit_on_error=False)
    def _certify(self, job: RunJob) -> None:
        result = run_job(self.settings, job, self.operator, self.control, self._event)
        self._post(self._ended, result)

    def _post(self, callback: Any, *args: Any) -> None:
        """Run `callback` on the UI thread; dropped once the screen is closing."""
        if self._closing:
            return
        try:
            self.app.call_from_thread(callback, *args)
        except Exception:
            if not self.app.is_running:  # it stopped between the check and the call
                self._closing = True
            else:  # a display bug must not stop a certification: log it and go on
                log.exception("the run screen could not show %s", getattr(callback, "__name__", callback))

    def _notice(self, notice: Notice) -> None:
        self._post(self._on_notice, notice)

    def _event(self, event: RunEvent) -> None:
        self._post(self._on_event, event)

    # -- from the worker (UI thread) -----------------------------------------------------------
    def _on_event(self, event: RunEvent) -> None:
        self.live.apply(event)
        if event.kind == ev.SHOT_LOST:
            self.notify(
                str(event.data.get("reason", "")),
                title=f"Shot {event.data['index']} lost",
                severity="warning",
            )
        if event.kind in (ev.MOI_MEASURED, ev.LOCATION_CHOSEN):
            self._predict_soon()
        self.refresh_view()

    def _on_notice(self, notice: Notice) -> None:
        if isinstance(notice, CannonRead):
            if notice.status is not None:
                self.live.cannon = notice.status
            self.live.cannon_error = notice.error
        elif isinstance(notice, GatesRead):
            self.live.gate_config = notice.config
        elif isinstance(notice, PromptPending) and not notice.is_fire:
            self.app.bell()
        self.refresh_view()

    def _ended(self, result: JobResult) -> None:
        outcome = result.outcome
        self.running, self.outcome, self.failure = False, outcome, result.failure
        # the session closed: it vented the cannon, and nothing reads its status any more
        self.live.cannon, self.live.cannon_error = None, ""
        self.live.cannon_note = "since the run ended\n(vented on closing; not read)"
        self.job = replace(self.job, run_id=result.run_id)
        if outcome is None:
            self.live.note(f"stopped by a fault: {result.failure}")
            self.notify(result.failure, title="Device fault: run stopped", severity="error", timeout=10)
        elif outcome.status is RunPhase.FINISHED:
            if self.live.verdict is None and outcome.verdict:
                self.live.verdict = outcome.verdict
            said = outcome.verdict.verdict if outcome.verdict else None
            self.notify(f"verdict: {said}", title="Run finished")
        else:
            self.notify(outcome.reason, title="Run interrupted (resumable)", severity="warning")
        if result.run_id:
            self.live.note(f"run {result.run_id[:8]}; records in {self.settings.db.name}")
            self.post_message(RunEnded(*self.left_open()))
        self.refresh_view()

    def left_open(self) -> tuple[LeftOpen, bool]:
        """The run as the console may leave it, and whether it is still open (resumable)."""
        outcome, run_id = self.outcome, self.job.run_id or ""
        reason = self.failure if outcome is None else outcome.reason
        still_open = outcome is None or outcome.status not in CLOSED
        return LeftOpen(run_id, reason, self.job.rig), still_open

    # -- the model's prediction -----------------------------------------------------------------
    def _predict_soon(self) -> None:
        moi = self.live.moi if self.live.moi is not None else self.job.bat.moi_kgm2
        if self.live.verdict is not None:
            return
        if moi is None:
            self.live.prediction_note = "after the MOI is measured"
            return
        locs = self.live.scan_locations or [6.0]
        self._predict(moi, self.live.best_location_in or locs[len(locs) // 2])

    @work(thread=True, exclusive=True, group="predict", exit_on_error=False)
    def _predict(self, moi: float, loc: float) -> None:
        self._post(self._predicted, *predict(self.job, moi, loc))

    def _predicted(self, value: float | None, note: str) -> None:
        if self.live.verdict is None:  # the run's own cross-check wins
            self.live.prediction, self.live.prediction_note = value, note
            self.refresh_view()

    # -- the view ------------------------------------------------------------------------------
    def situation(self) -> Situation:
        """The state the keys and the prompt line depend on."""
        return Situation(
            running=self.running,
            prompt=self.operator.pending if self.running else None,
            paused=self.control.paused,
            aborting=self.control.aborted,
            cannon=self.live.cannon,
            cannon_error=self.live.cannon_error,
            ended=self.outcome.status if self.outcome else None,
            reason=self.outcome.reason if self.outcome else "",
            failure=self.failure,
            ring_check=self.job.procedure.ring_check,
            one_key=self.job.config.console.one_key,
        )

    def essentials(self) -> Text:
        """The rig, the prompt, the live metric and the verdict or fault: for a too-small terminal."""
        text = Text(self._title(), style="bold")
        now = self.situation()
        for part in (situation.prompt_text(now), situation.message_text(now, self.live)):
            if part.plain:
                text.append("\n\n")
                text.append_text(part)
        s = self.live.shot
        if s is not None and s.metric is not None:
            text.append(f"\n\nshot {s.index}: {self.live.metric_name} {s.metric:.4f} ± {s.u or 0.0:.4f}")
        return text

    def _title(self) -> str:
        p, bat = self.job.procedure, self.job.bat
        return f"{self.job.rig_label} · {p.name} · bat {bat.id}"

    def fire_block(self) -> str:
        """Why the fire key is off now ('' when the waiting shot may be fired)."""
        return situation.fire_block(self.situation())

    def refresh_view(self) -> None:
        """Redraw every panel from the folded state, append new log lines, re-check the keys."""
        if not self.is_mounted:
            return
        panels: dict[str, Callable[[LiveRun], Text]] = {
            "cannon": render.cannon_panel,
            "gates": render.gates_panel,
            "shot": render.shot_panel,
            "progress": render.progress_panel,
        }
        # the wide panels: hidden below 120x40, cheap to draw
        panels |= {"scan-plot": render.scan_plot, "hits-plot": render.hits_plot}
        panels |= {"budget": render.budget_panel}
        rows = self.query_one("#traffic", Static).content_size.height
        panels["traffic"] = lambda live: render.traffic_panel(live, max(rows, 1))  # the newest lines
        now = self.situation()
        texts = {name: draw(self.live) for name, draw in panels.items()}
        texts |= {"prompt": situation.prompt_text(now), "message": situation.message_text(now, self.live)}
        for name, text in texts.items():
            if self._shown.get(name) != text:  # an unchanged panel is not laid out and drawn again
                self._shown[name] = text
                # the boxes' sizes are fixed by the CSS: only the prompt and message lines, whose
                # height follows their text, need the screen laid out again
                self.query_one(f"#{name}", Static).update(text, layout=name in SIZED_BY_TEXT)
        log = self.query_one("#log", RichLog)
        for line in self.live.log[self._logged :]:
            log.write(line)
        self._logged = len(self.live.log)
        keys = tuple(situation.allowed(now, action) for action in situation.RUN_KEYS)
        if keys != self._keys_state:  # the key bar and bindings: only when the keys change
            self._keys_state = keys
            self.refresh_bindings()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        return situation.allowed(self.situation(), action)

    def on_unmount(self) -> None:
        # never leave the worker blocked on a prompt: the process could not exit
        self.control.abort()
        self.operator.cancel("the console closed")
        self._closing = True
