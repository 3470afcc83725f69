"""What the operator may do now and what the console asks of them (pure: testable without a UI)."""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text

from rig.core.devices import CannonStatus
from rig.core.run_phase import CLOSED, RunPhase
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
    ended: RunPhase | None = None  # the outcome's phase once the run has stopped: finished | interrupted
    reason: str = ""  # why it was interrupted
    failure: str = ""  # the error that stopped it (a device fault)
    ring_check: bool = False  # whether the procedure asks for ring checks
    one_key: bool = False  # the lab lets Enter answer the ring checks ahead (rig config [console])


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


RUN_KEYS = ("fire", "fire_off", "quick", "answer", "pause", "go_on", "abort", "resume", "back")
PAUSED = ("PAUSED", "bold reverse")


def quick_answer(prompt_id: str, ring_check: bool, one_key: bool = False) -> tuple[str, ...] | None:
    """What Enter answers yes with the pending prompt (None: Enter does not answer it, e.g. a fire).

    Each inspection is asked on its own prompt; only a lab that chose `one_key` (rig config
    [console]) has Enter also pass the ring checks that come next with nothing hitting the bat
    between, and the record says each came with that answer (OperatorAnswered.given)."""
    kind, _, number = prompt_id.rpartition("-")
    if prompt_id == "ball" or kind == "ring-before":
        return ()
    if not number.isdigit() or not ring_check or not one_key:
        return () if kind in ("review", "ring-after") else None
    after, before = f"ring-after-{number}", f"ring-before-{int(number) + 1}"
    if kind == "review":  # accept the shot and pass the ring check after it (and before the next)
        return (after, before)
    if kind == "ring-after":  # the bat is not hit between this check and the next shot's
        return (before,)
    return None


QUICK_HINT = {
    "review": "Enter/y: accept  n: reject",
    "ring-after": "Enter/y: passes  n: fails",
    "ring-before": "Enter/y: passes  n: fails",
    "ball": "Enter/y: done  n: stop the run",
}
ONE_KEY_HINT = {  # a lab's one key ([console] one_key): the record says which answers came with it
    "review": "Enter: accept, and the ring passes (recorded as given with the acceptance)  y: accept only"
    "  n: reject",
    "ring-after": "Enter: passes, also before the next shot (recorded so)  y: passes  n: fails",
}


def allowed(s: Situation, action: str) -> bool | None:
    """Whether a run-screen key works now: True, None (shown but off) or False (hidden)."""
    if action == "fire":  # paused: not offered at all (p goes on first); otherwise shown but off
        return True if not fire_block(s) else (None if s.running and not s.paused else False)
    if action == "fire_off":  # the hidden f that says why the shot is not fired
        return s.running and bool(fire_block(s))
    if action == "answer":
        return s.prompt is not None and not s.prompt.is_fire
    if action == "quick":
        return s.prompt is not None and quick_answer(s.prompt.prompt_id, s.ring_check, s.one_key) is not None
    if action == "pause":
        return s.running and not s.paused
    if action == "go_on":
        return s.running and s.paused
    if action == "abort":
        return s.running
    if action == "resume":  # after an interruption or a fault: a run still open
        return not s.running and s.ended not in CLOSED
    if action == "back":
        return not s.running
    return True


def prompt_text(s: Situation) -> Text:
    """The line that says what the console wants from the operator now."""
    if s.running and s.aborting:
        return Text("Aborting: the run stops before the next shot", style="bold")
    if s.running and s.paused:  # said first, whatever waits: nothing is fired until p
        text = Text.assemble(PAUSED, (" p goes on", "bold"))
        if s.prompt is not None:
            text.append("  ")
            text.append_text(_asked(s))
        else:
            text.append(": the run holds before the next shot")
        return text
    return _asked(s) if s.prompt is not None else _idle(s)


def _asked(s: Situation) -> Text:
    """The waiting prompt and the keys that answer it (a fire while paused: that it waits)."""
    assert s.prompt is not None
    if s.prompt.is_fire and s.paused:
        return Text.assemble((s.prompt.text, "bold"), " waits")
    if s.prompt.is_fire:
        blocked = fire_block(s)
        if blocked:
            return Text(f"FIRE DISABLED: {blocked}", style="bold red")
        return Text.assemble((s.prompt.text, "bold"), "  f: arm and fire")
    pid = s.prompt.prompt_id
    kind = pid if pid == "ball" else pid.rpartition("-")[0]
    hint = QUICK_HINT.get(kind, "y: yes  n: no")
    if s.one_key and s.ring_check:
        hint = ONE_KEY_HINT.get(kind, hint)
    return Text.assemble((s.prompt.text, "bold"), "  ", (hint, "reverse"))


def _idle(s: Situation) -> Text:
    """Nothing asked: running, or how the run ended and what the keys do then."""
    if s.running:
        return Text("Running...", style="bold")
    if s.failure:
        return Text("Stopped by a fault: fix the rig, then r resumes the run, b goes back", style="bold")
    if s.ended is not None and s.ended not in CLOSED:
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
    shot = live.shot
    if shot is not None and shot.status in ("invalid", "lost"):  # why, in full: it decides a re-shoot
        why = "; ".join(shot.reasons) or "no reason given"
        return Text(f"shot {shot.index} {shot.status.upper()}: {why}", style="yellow")
    return Text(live.cannon_error and f"cannon: {live.cannon_error}", style="red")
