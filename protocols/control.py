"""Who answers a run's prompts, how a UI steers a run, and how a run stops early."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from rig.core import events as ev
from rig.core.errors import RigError

ASKED = "asked"  # a person answered this prompt's own question
WITH = "with"  # given by the key that answered another prompt (Answer.with_prompt)
SCRIPT = ev.BY_SCRIPT  # a script answered: nobody was shown the question
GIVEN = (ASKED, WITH, SCRIPT)


@dataclass(frozen=True)
class Answer:
    """An answer and how it was given, as the record keeps it: an inspection counts as done only
    when `given` is ASKED (rig.core.events.OperatorAnswered)."""

    value: bool
    given: str = ASKED
    with_prompt: str | None = None  # the prompt whose answer gave this one (given WITH)

    def __post_init__(self) -> None:
        if self.given not in GIVEN:
            raise ValueError(f"an answer is given {', '.join(GIVEN)}, not {self.given!r}")
        if (self.given == WITH) != (self.with_prompt is not None):
            raise ValueError("an answer given with another names that prompt, and only then")


@dataclass(frozen=True)
class Rolling:
    """A rolling step as the operator reports it (accelerated break-in): what was done and by whom,
    how the report was given (as Answer), and the hoop frequency if it was measured after (Hz, u)."""

    depth_in: float
    passes: int
    who: str
    given: str = ASKED
    hoop_hz: float | None = None
    hoop_u_hz: float | None = None

    def __post_init__(self) -> None:
        if self.given not in GIVEN:
            raise ValueError(f"a rolling is given {', '.join(GIVEN)}, not {self.given!r}")
        if not (0.0 <= self.depth_in <= 0.5 and 0 <= self.passes <= 1000 and self.who.strip()):
            raise ValueError(
                f"a rolling needs a depth of 0-0.5 in, 0-1000 passes and who: not "
                f"{self.depth_in!r} in, {self.passes!r}, {self.who!r}"
            )


@runtime_checkable
class RollingOperator(Protocol):
    """An operator who rolls a barrel when asked (depth and passes asked for) and says what was done."""

    def roll(self, prompt_id: str, text: str, depth_in: float, passes: int) -> Rolling: ...


class Operator(Protocol):
    """Answers the operator prompts (ring check, ball replacement): an Answer, or a bare bool
    when the operator does not say how it was given (recorded as not stated)."""

    def ask(self, prompt_id: str, text: str) -> Answer | bool: ...


@dataclass
class ScriptedOperator:
    """An operator for scripted runs: answers every prompt the same way, recorded as such."""

    answer: bool = True
    who: str = "script"

    def ask(self, prompt_id: str, text: str) -> Answer:
        """Return the scripted answer, marked as given by the script (no inspection was made)."""
        return Answer(self.answer, SCRIPT)

    def roll(self, prompt_id: str, text: str, depth_in: float, passes: int) -> Rolling:
        """Report the rolling asked for, marked as given by the script (nobody said it was done)."""
        return Rolling(depth_in, passes, self.who, SCRIPT)


class RunControl:
    """Commands from a UI to a running procedure: pause, resume, abort (thread-safe)."""

    def __init__(self) -> None:
        self._go = threading.Event()
        self._go.set()
        self._abort = threading.Event()
        self.reason = "aborted by the operator"
        self.settled = False  # the run's outcome is being recorded: nothing is left to stop

    def pause(self) -> None:
        """Hold before the next shot."""
        self._go.clear()

    def resume(self) -> None:
        """Go on after a pause."""
        self._go.set()

    def abort(self, reason: str = "aborted by the operator") -> None:
        """Stop before the next shot (the one in progress is recorded first); the run stays resumable."""
        if not self._abort.is_set():
            self.reason = reason
        self._abort.set()
        self._go.set()

    @property
    def paused(self) -> bool:
        """Whether a pause is in force."""
        return not self._go.is_set()

    @property
    def aborted(self) -> bool:
        """Whether an abort was asked for."""
        return self._abort.is_set()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block while paused; True once free to go on."""
        return self._go.wait(timeout_s)


class RunAborted(RigError):
    """The run cannot go on; the reason is recorded and the run can be resumed after a fix."""


class BudgetExceeded(RunAborted):
    """More invalid shots than the procedure allows since the rig was last checked."""


class PlanError(RigError):
    """A plan asked the executor for something it must refuse (a shot without its recorded intent,
    a second shot while one is unresolved, a plan that does not end): a bug in the plan."""
