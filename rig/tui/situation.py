"""What the operator may do now and what the console asks of them (pure: testable without a UI)."""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text

from rig.core.devices import CannonStatus
from rig.tui.live import LiveRun
from rig.tui.operator import PromptPending
from rig.tui.render import verdict_text


@dataclass(frozen=True)
class Situation:
    """A snapshot of the run screen's state, as far as the keys are concerned."""

    running: bool
    prompt: PromptPending | None
    paused: bool = False
    aborting: bool = False
    cannon: CannonStatus | None = None
    cannon_error: str = ""
    ended: str = ""  # the outcome's status once the run has ended: finished | interrupted
    reason: str = ""  # why it was interrupted
    failure: str = ""  # the error that stopped it (a device fault)


def fire_block(s: Situation) -> str:
    """Why the fire key is off now ('' when the waiting shot may be fired)."""
    if not s.running or s.prompt is None or not s.prompt.is_fire:
        return "no shot is waiting to be fired"
    if s.paused:
        return "paused"
    if s.cannon_error or s.cannon is None:
        return f"cannon status unknown ({s.cannon_error or 'not read yet'})"
    if not s.cannon.interlocks.all_closed:  # the driver refuses too; the key says so first
        return "interlock open: " + ", ".join(s.cannon.interlocks.open_names())
    return ""


RUN_KEYS = ("fire", "answer", "pause", "abort", "resume", "back")


def allowed(s: Situation, action: str) -> bool | None:
    """Whether a run-screen key works now: True, None (shown but off) or False (hidden)."""
    if action == "fire":
        return True if not fire_block(s) else (None if s.running else False)
    if action == "answer":
        return s.prompt is not None and not s.prompt.is_fire
    if action in ("pause", "abort"):
        return s.running
    if action == "resume":  # after an interruption or a fault
        return not s.running and s.ended != "finished"
    if action == "back":
        return not s.running
    return True


def prompt_text(s: Situation) -> Text:
    """The line that says what the console wants from the operator now."""
    if s.running and s.aborting:
        return Text("Aborting: the run stops before the next shot", style="bold")
    if s.prompt is not None and s.prompt.is_fire:
        blocked = fire_block(s)
        if blocked:
            return Text(f"FIRE DISABLED: {blocked}", style="bold red")
        return Text.assemble((s.prompt.text, "bold"), "  f: arm and fire")
    if s.prompt is not None:
        return Text.assemble((s.prompt.text, "bold"), "  y: yes  n: no")
    if s.running:
        return Text("Paused: p goes on" if s.paused else "Running...", style="bold")
    if s.failure:
        return Text("Stopped by a fault: fix the rig, then r resumes the run, b goes back", style="bold")
    if s.ended and s.ended != "finished":
        return Text("Interrupted (resumable): r resumes the run, b back to set-up", style="bold")
    return Text("Run finished: b back to set-up, h history", style="bold")


def message_text(s: Situation, live: LiveRun) -> Text:
    """The verdict at the end, or the last fault."""
    if s.failure:
        return Text(f"FAULT: {s.failure}", style="bold red")
    if live.verdict:
        return verdict_text(live)
    if live.interrupted:
        return Text(f"interrupted: {live.interrupted}", style="yellow")
    return Text(live.cannon_error and f"cannon: {live.cannon_error}", style="red")
