"""The run screen's keys: each one sends a command (an answer, pause, abort), none touches a device."""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, Any

from textual.worker import Worker, WorkerCancelled, WorkerFailed

from rig.protocols.control import RunControl
from rig.tui.messages import OpenHistory
from rig.tui.modals import ConfirmScreen
from rig.tui.operator import ConsoleOperator
from rig.tui.rigs import ConsoleSettings, RunJob
from rig.tui.situation import quick_answer

if TYPE_CHECKING:
    from textual.app import App
    from textual.message import Message


class RunKeys:
    """Actions of the run screen (mixed into RunScreen, which owns the state they use)."""

    _withdrawn_fail: str | None = None  # a ring check failed with n, then withdrawn: Enter won't pass it

    if TYPE_CHECKING:  # provided by RunScreen and Screen; nothing is defined here at run time
        app: App[Any]
        settings: ConsoleSettings
        job: RunJob
        operator: ConsoleOperator
        control: RunControl
        running: bool
        _worker: Worker[None] | None

        def fire_block(self) -> str: ...
        def refresh_view(self) -> None: ...
        def start(self) -> None: ...
        def notify(self, message: str, **kw: Any) -> None: ...
        def dismiss(self, result: None = None) -> Any: ...
        def post_message(self, message: Message) -> bool: ...

    def action_fire(self) -> None:
        """Fire the waiting shot: the key is the operator's confirmation (off while fire_block says why)."""
        prompt = self.operator.pending
        if prompt is None or not prompt.is_fire:
            return
        blocked = self.fire_block()  # checked again at the key: the interlocks may have opened
        if blocked:
            self.notify(f"not fired: {blocked}", severity="error")
            return
        self.operator.answer(prompt.prompt_id, True)

    def action_fire_off(self) -> None:
        """f while the shot may not be fired (the footer does not offer Fire then): say why."""
        blocked = "paused (p goes on)" if self.control.paused else self.fire_block()
        self.notify(f"not fired: {blocked}", severity="warning")

    def action_quick(self) -> None:
        """Enter: the answer that needs no thought (a ring check passes, a valid shot is accepted);
        not on a ring check whose fail was just withdrawn: that one needs y or n."""
        prompt = self.operator.pending
        if prompt is not None and prompt.prompt_id == self._withdrawn_fail:
            self.notify("the ring check was failed, then withdrawn: answer it with y (passes) or n (fails)")
            return
        then = (
            None
            if prompt is None
            else quick_answer(
                prompt.prompt_id, self.job.procedure.ring_check, self.job.config.console.one_key
            )
        )
        if then and self.control.paused:
            then = ()  # paused: the bat may be handled before the run goes on, so no answers ahead
        if prompt is not None and then is not None:
            self.operator.answer(prompt.prompt_id, True, then)

    def action_answer(self, value: bool) -> None:
        """Answer the pending yes/no prompt; a failed ring check (it fails the bat) asks first."""
        prompt = self.operator.pending
        if prompt is None or prompt.is_fire:
            return
        if value or not prompt.prompt_id.startswith("ring-"):
            self.operator.answer(prompt.prompt_id, value)
            return

        def confirmed(yes: bool | None) -> None:
            if yes:
                self.operator.answer(prompt.prompt_id, False)
            else:  # withdrawn: Enter must not now pass what the operator just failed
                self._withdrawn_fail = prompt.prompt_id
                self.operator.drop_answers_ahead()

        self.app.push_screen(
            ConfirmScreen("The ring does not pass: the run ends with FAIL (barrel deformed). Record that?"),
            confirmed,
        )

    def action_pause(self) -> None:
        """Hold before the next shot, or go on."""
        if self.control.paused:
            self.operator.drop_answers_ahead()
            self.control.resume()
        else:
            self.control.pause()
            self.operator.drop_answers_ahead()  # the bat may be handled: ring checks are asked again
            self.notify("the run holds before the next shot", title="Pause")
        self.refresh_view()

    def action_go_on(self) -> None:
        """End the pause (p while paused)."""
        self.action_pause()

    def action_abort(self) -> None:
        """Stop before the next shot (asks first); the run stays resumable."""

        def confirmed(yes: bool | None) -> None:
            if yes and self.running:
                self.stop("aborted by the operator")
                self.refresh_view()

        self.app.push_screen(
            ConfirmScreen("Abort the run? It stops before the next shot and can be resumed later."), confirmed
        )

    def stop(self, reason: str) -> None:
        """Abort: the runner stops at its next hold; a prompt before a shot is withdrawn now."""
        self.control.abort()
        self.operator.drop_answers_ahead()
        prompt = self.operator.pending
        if prompt is None or not prompt.prompt_id.startswith("ring-after-"):
            self.operator.cancel(reason)  # the ring check after a hit is still worth answering

    def action_resume(self) -> None:
        """Resume the interrupted (or faulted) run from its record."""
        if not self.running:
            self.start()

    def action_back(self) -> None:
        """Back to the set-up screen."""
        self.dismiss(None)

    def action_history(self) -> None:
        """Past runs (the run goes on underneath)."""
        self.post_message(OpenHistory())

    async def finish(self, reason: str) -> None:
        """Stop the run and wait for its worker (the app is quitting)."""
        if self.running and self._worker is not None:
            self.operator.cancel(reason)
            self.stop(reason)
            with contextlib.suppress(WorkerCancelled, WorkerFailed):
                await self._worker.wait()
