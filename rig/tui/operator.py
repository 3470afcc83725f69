"""The console's side of the runner's Operator interface: prompts wait for the operator's keys.

The runner calls `ask` on its worker thread; the call blocks on a threading.Event until the UI
thread answers (or cancels). While it waits the runner is idle, so the same thread may read the
cannon's status through the open session: that is how the console shows the interlocks live
without ever touching a device from the UI thread.
"""

from __future__ import annotations

import contextlib
import getpass
import threading
from collections.abc import Callable
from dataclasses import dataclass

from rig.core.devices import CannonStatus, GateConfig
from rig.core.errors import RigError
from rig.protocols.control import ASKED, WITH, Answer, RunAborted
from rig.session import RigSession


@dataclass(frozen=True)
class PromptPending:
    """The runner asks the operator something; `prompt_id` as in rig.protocols.steps."""

    prompt_id: str
    text: str

    @property
    def is_fire(self) -> bool:
        """Whether this prompt is the confirmation of a shot (answered with the fire key)."""
        return self.prompt_id.startswith("fire-")


@dataclass(frozen=True)
class PromptClosed:
    """The pending prompt was answered (or cancelled)."""

    prompt_id: str


@dataclass(frozen=True)
class CannonRead:
    """The cannon's status as read while the runner waited; `error` when the read failed."""

    status: CannonStatus | None
    error: str = ""


@dataclass(frozen=True)
class GatesRead:
    """The gates' counter configuration, read once when the session opened."""

    config: GateConfig


Notice = PromptPending | PromptClosed | CannonRead | GatesRead


def _who() -> str:
    try:
        return f"console ({getpass.getuser()})"
    except (KeyError, OSError):  # no login name in some containers
        return "console"


class ConsoleOperator:
    """Blocks the runner's thread on each prompt until the UI answers; polls the cannon meanwhile."""

    def __init__(self, publish: Callable[[Notice], None], poll_s: float = 0.5) -> None:
        self.who = _who()
        self._publish = publish
        self._poll_s = poll_s
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._pending: PromptPending | None = None
        self._answer = False
        self._cancel_reason = ""
        self._read_status: Callable[[], CannonStatus] | None = None
        self._standing: tuple[str, ...] = ()  # ring checks already answered yes, in order
        self._standing_with = ""  # the prompt whose key answered them

    # -- runner side (worker thread) ---------------------------------------------------------
    def attach(self, session: RigSession) -> None:
        """Called by certify with the open session: remember how to read the cannon's status."""
        self._read_status = session.cannon.status
        with contextlib.suppress(RigError):  # the runner reads it again and reports a failure
            self._publish(GatesRead(session.gates.config()))
        self.poll()

    def poll(self) -> None:
        """Read the cannon's status and publish it (only on the runner's thread, while it waits)."""
        if self._read_status is None:
            return
        try:
            self._publish(CannonRead(self._read_status()))
        except RigError as exc:
            self._publish(CannonRead(None, str(exc)))

    def ask(self, prompt_id: str, text: str) -> Answer:
        """Publish the prompt and wait for the operator's answer; a cancel stops the run (resumable).
        A ring check answered ahead (`answer`'s `then`) is not shown: its answer says which key gave it."""
        prompt = PromptPending(prompt_id, text)
        with self._lock:
            if self._cancel_reason:
                raise RunAborted(self._cancel_reason)
            if prompt_id in self._standing:  # answered with an earlier key: nothing happened since
                self._standing = self._standing[self._standing.index(prompt_id) + 1 :]
                return Answer(True, WITH, self._standing_with)
            if prompt_id != "ball":  # a new ball does not touch the bat; anything else ends them
                self._standing = ()
            self._pending, self._answer = prompt, False
            self._done.clear()
        self._publish(prompt)
        self.poll()
        while not self._done.wait(self._poll_s):
            self.poll()
        with self._lock:
            self._pending = None
            answer, reason = self._answer, self._cancel_reason
        self._publish(PromptClosed(prompt_id))
        if reason:
            raise RunAborted(reason)
        return Answer(answer, ASKED)

    # -- UI side -----------------------------------------------------------------------------
    @property
    def pending(self) -> PromptPending | None:
        """The prompt waiting for an answer, if any."""
        return self._pending

    def answer(self, prompt_id: str, value: bool, then: tuple[str, ...] = ()) -> bool:
        """Answer the pending prompt if it is still `prompt_id`; False if it is not pending.

        `then`: ring checks the operator passes with the same key; each is answered yes when the
        runner asks it next (a new ball between is allowed), and dropped when anything else comes
        first. Only ring checks: a fire is never answered in advance.
        """
        if any(not p.startswith("ring-") for p in then):
            raise ValueError(f"only ring checks can be answered in advance, not {then}")
        with self._lock:
            if self._pending is None or self._pending.prompt_id != prompt_id or self._done.is_set():
                return False
            self._answer = value
            if prompt_id != "ball" or not value:  # a new ball does not touch the bat: checks stand
                self._standing = then if value else ()
                self._standing_with = prompt_id
            self._done.set()
            return True

    def drop_answers_ahead(self) -> None:
        """Forget ring checks answered in advance: after a pause, an abort or a withdrawn fail
        something may have happened to the bat, so each is asked again."""
        with self._lock:
            self._standing = ()

    def cancel(self, reason: str) -> None:
        """Stop waiting: the pending (and any later) prompt raises RunAborted with `reason`."""
        with self._lock:
            if not self._cancel_reason:
                self._cancel_reason = reason
            self._done.set()
