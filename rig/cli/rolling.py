"""The accelerated break-in's rolling prompts: what a person reports after rolling a barrel.

At a terminal (`rig certify --procedure abi --config RIG.toml`), each rolling step the plan asks for
is reported from prompts: the depth rolled (inches), the passes, who rolled it and, if the barrel
was tapped after, its hoop frequency (Hz; blank: not tapped); then, after each stage's BBCOR, the
inspection (y/n). A bad answer gets one line saying why and the question again; an empty answer
takes the default shown in brackets (what the plan asked for). In a scripted or simulated run the
script reports what the plan asked for, recorded as given by a script (`hands`: the simulated
barrel is rolled so, and tapped: rig.sim_break_in).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

from rig.core import events as ev
from rig.protocols.control import ASKED, SCRIPT, Answer, Rolling, RunAborted, ScriptedOperator

T = TypeVar("T")
MAX_DEPTH_IN = 0.5  # rig.protocols.control.Rolling's bound
MAX_PASSES = 1000
POLL_S = 0.2  # how often a prompt that waits looks for a stop
HOOP_RANGE_HZ = (300.0, 10000.0)  # [assumed] a bat barrel's first hoop mode lies well inside this


def parse_depth(text: str) -> float:
    """A rolled depth in inches ('0.0125' or '0.0125 in'); ValueError (one line) otherwise."""
    body = text.strip().removesuffix("in").strip().removesuffix('"').strip()
    try:
        depth = float(body)
    except ValueError:
        raise ValueError(f"{text.strip()!r} is not a depth in inches (e.g. 0.0125)") from None
    if not (math.isfinite(depth) and 0.0 < depth <= MAX_DEPTH_IN):
        raise ValueError(f"a depth of {depth:g} in is outside 0-{MAX_DEPTH_IN:g} in")
    return depth


def parse_passes(text: str) -> int:
    """A whole number of passes, 1 to 1000; ValueError (one line) otherwise."""
    try:
        passes = int(text.strip())
    except ValueError:
        raise ValueError(f"{text.strip()!r} is not a whole number of passes") from None
    if not 1 <= passes <= MAX_PASSES:
        raise ValueError(f"{passes} passes: give 1 to {MAX_PASSES}")
    return passes


def parse_who(text: str) -> str:
    """Who rolled the barrel: 1-200 printable characters."""
    who = text.strip()
    if not who or len(who) > 200 or not who.isprintable():
        raise ValueError("who rolled it: a name of 1-200 printable characters")
    return who


def parse_hoop(text: str) -> float | None:
    """The hoop frequency tapped after rolling, Hz; blank: not tapped (None)."""
    body = text.strip().removesuffix("Hz").removesuffix("hz").strip()
    if not body:
        return None
    try:
        hoop = float(body)
    except ValueError:
        raise ValueError(f"{text.strip()!r} is not a frequency in Hz (blank if not tapped)") from None
    lo, hi = HOOP_RANGE_HZ
    if not (math.isfinite(hoop) and lo <= hoop <= hi):
        raise ValueError(f"{hoop:g} Hz is outside {lo:g}-{hi:g} Hz, a barrel's hoop range")
    return hoop


def parse_yes_no(text: str) -> bool:
    """y/yes or n/no."""
    word = text.strip().lower()
    if word in ("y", "yes"):
        return True
    if word in ("n", "no"):
        return False
    raise ValueError(f"{text.strip()!r}: answer y or n")


def ask_until(
    question: str,
    parse: Callable[[str], T],
    read: Callable[[str], str],
    say: Callable[[str], None],
    default: str | None = None,
) -> T:
    """Ask `question` until `parse` takes the answer (blank: `default`, when there is one); each bad
    answer is one line saying why. End of input stops the run (it stays resumable)."""
    shown = f"{question} [{default}]: " if default else f"{question}: "
    while True:
        try:
            text = read(shown)
        except EOFError:
            raise RunAborted(f"no answer to {question!r}: the terminal's input ended") from None
        if not text.strip() and default is not None:
            text = default
        try:
            return parse(text)
        except ValueError as exc:
            say(f"rig: {exc}; try again")


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def terminal_reader(stopped: Callable[[], str | None] = lambda: None) -> Callable[[str], str]:
    """Read an answer from the terminal after writing its prompt to stderr; while waiting, a stop
    (Ctrl-C, SIGTERM: `stopped()` gives its reason) stops the run at once, resumable."""
    import select

    def read(prompt: str) -> str:
        sys.stderr.write(prompt)
        sys.stderr.flush()
        while not select.select([sys.stdin], [], [], POLL_S)[0]:
            why = stopped()
            if why is not None:
                sys.stderr.write("\n")
                raise RunAborted(why)
        line = sys.stdin.readline()
        if not line:
            raise EOFError
        return line.rstrip("\n")

    return read


@dataclass
class TerminalRoller:
    """A person at the terminal reports each rolling and answers each inspection (recorded as asked);
    the other prompts are answered as a scripted run answers them. `rolled_by`: the default name."""

    who: str = "operator at the terminal"
    rolled_by: str | None = None
    read: Callable[[str], str] = field(default_factory=terminal_reader)
    say: Callable[[str], None] = _say

    def ask(self, prompt_id: str, text: str) -> Answer:
        """The inspection after a stage is asked (y/n); other prompts as a script answers them."""
        if not prompt_id.startswith(ev.ABI_DAMAGE_PROMPT):
            return Answer(True, SCRIPT)
        self.say(text)
        return Answer(ask_until("Free of damage? (y/n)", parse_yes_no, self.read, self.say), ASKED)

    def roll(self, prompt_id: str, text: str, depth_in: float, passes: int) -> Rolling:
        """Show what to roll, then ask what was rolled, by whom, and the hoop frequency if tapped."""
        self.say(text)
        depth = ask_until("Depth rolled, in", parse_depth, self.read, self.say, f"{depth_in:g}")
        done = ask_until("Passes", parse_passes, self.read, self.say, str(passes))
        who = ask_until("Rolled by", parse_who, self.read, self.say, self.rolled_by)
        hoop = ask_until(
            "Hoop frequency tapped after, Hz (blank: not tapped)", parse_hoop, self.read, self.say
        )
        return Rolling(depth, done, who, ASKED, hoop)


@dataclass
class ScriptedRoller(ScriptedOperator):
    """A scripted or simulated run's operator: every prompt answered by the script, each rolling
    reported as the plan asked (by `rolled_by`, else the script), `hands` rolling the simulated barrel."""

    rolled_by: str | None = None
    hands: Callable[[float, int], tuple[float, float]] | None = None

    def roll(self, prompt_id: str, text: str, depth_in: float, passes: int) -> Rolling:
        """Roll as asked and report it, given by the script; on a simulated barrel, with the hoop
        frequency (and u) its tap after the rolling found."""
        if self.hands is None:
            return Rolling(depth_in, passes, self.rolled_by or "script", SCRIPT)
        hoop, u = self.hands(depth_in, passes)
        return Rolling(depth_in, passes, self.rolled_by or "script", SCRIPT, hoop, u)
