"""The accelerated break-in's rolling prompts (rig.cli.rolling): each answer parsed or refused in one
line and asked again, defaults from the plan's request, end of input stopping the run; the scripted
roller reports what the plan asked, by script, and rolls the simulated barrel with it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.cli import main
from rig.cli.rolling import (
    ScriptedRoller,
    TerminalRoller,
    ask_until,
    parse_depth,
    parse_hoop,
    parse_passes,
    parse_who,
    parse_yes_no,
)
from rig.core import events as ev
from rig.protocols.control import ASKED, SCRIPT, RunAborted


class Terminal:
    """Typed answers, one per question, and the lines the prompts printed."""

    def __init__(self, *answers: str) -> None:
        self.answers: Iterator[str] = iter(answers)
        self.asked: list[str] = []
        self.said: list[str] = []

    def read(self, question: str) -> str:
        self.asked.append(question)
        try:
            return next(self.answers)
        except StopIteration:
            raise EOFError from None

    def say(self, line: str) -> None:
        self.said.append(line)


@pytest.mark.parametrize(
    ("text", "depth"), [("0.0125", 0.0125), (" 0.025 in", 0.025), ('0.05"', 0.05), ("0.5", 0.5)]
)
def test_a_depth_is_read_in_inches(text: str, depth: float) -> None:
    assert parse_depth(text) == depth


@pytest.mark.parametrize(
    ("parse", "text", "why"),
    [
        (parse_depth, "abc", "is not a depth in inches"),
        (parse_depth, "0", "outside 0-0.5 in"),
        (parse_depth, "0.6", "outside 0-0.5 in"),
        (parse_depth, "nan", "outside 0-0.5 in"),
        (parse_depth, "12 mm", "is not a depth in inches"),
        (parse_passes, "4.5", "is not a whole number of passes"),
        (parse_passes, "0", "give 1 to 1000"),
        (parse_passes, "1001", "give 1 to 1000"),
        (parse_who, "   ", "a name of 1-200 printable characters"),
        (parse_who, "a\tb", "a name of 1-200 printable characters"),
        (parse_hoop, "fast", "is not a frequency in Hz"),
        (parse_hoop, "120", "outside 300-10000 Hz"),
        (parse_yes_no, "maybe", "answer y or n"),
    ],
)
def test_a_bad_answer_is_refused_in_one_line(parse: object, text: str, why: str) -> None:
    with pytest.raises(ValueError) as caught:
        parse(text)  # type: ignore[operator]
    assert why in str(caught.value) and "\n" not in str(caught.value)


def test_the_hoop_is_optional_and_read_in_hz() -> None:
    assert parse_hoop("") is None and parse_hoop("  ") is None
    assert parse_hoop("1725") == 1725.0 and parse_hoop("1725 Hz") == 1725.0
    assert parse_passes(" 8 ") == 8 and parse_who("  B. Roller ") == "B. Roller"
    assert parse_yes_no("Y") is True and parse_yes_no("no") is False


def test_a_question_is_asked_again_after_a_bad_answer_and_a_blank_takes_the_default() -> None:
    term = Terminal("x", "-1", "", "0.0375")
    assert ask_until("Depth rolled, in", parse_depth, term.read, term.say, "0.0125") == 0.0125
    assert term.asked == ["Depth rolled, in [0.0125]: "] * 3
    assert term.said == [
        "rig: 'x' is not a depth in inches (e.g. 0.0125); try again",
        "rig: a depth of -1 in is outside 0-0.5 in; try again",
    ]
    assert ask_until("Depth rolled, in", parse_depth, term.read, term.say, "0.0125") == 0.0375


def test_without_a_default_a_blank_answer_is_asked_again() -> None:
    term = Terminal("", "C. Roller")
    assert ask_until("Rolled by", parse_who, term.read, term.say) == "C. Roller"
    assert term.asked == ["Rolled by: ", "Rolled by: "] and len(term.said) == 1


def test_end_of_input_stops_the_run_resumably() -> None:
    term = Terminal()
    with pytest.raises(RunAborted) as caught:
        ask_until("Passes", parse_passes, term.read, term.say, "4")
    assert "the terminal's input ended" in str(caught.value)


def test_a_person_reports_the_rolling_at_the_terminal() -> None:
    term = Terminal("0.02", "abc", "6", "", "1710")
    roller = TerminalRoller(rolled_by="B. Roller", read=term.read, say=term.say)
    said = roller.roll("abi-roll-1", "Roll the barrel: 4 passes at 0.0125 in depth", 0.0125, 4)
    assert (said.depth_in, said.passes, said.who, said.given, said.hoop_hz) == (
        0.02,
        6,
        "B. Roller",
        ASKED,
        1710.0,
    )
    assert term.said[0].startswith("Roll the barrel") and term.said[1].startswith("rig: 'abc'")
    assert term.asked == [
        "Depth rolled, in [0.0125]: ",
        "Passes [4]: ",
        "Passes [4]: ",
        "Rolled by [B. Roller]: ",
        "Hoop frequency tapped after, Hz (blank: not tapped): ",
    ]


def test_the_inspection_is_asked_and_other_prompts_are_scripted() -> None:
    term = Terminal("perhaps", "n")
    roller = TerminalRoller(read=term.read, say=term.say)
    answer = roller.ask(f"{ev.ABI_DAMAGE_PROMPT}1", "Inspect the barrel")
    assert (
        answer.value is False and answer.given == ASKED and term.said[-1].endswith("answer y or n; try again")
    )
    ring = roller.ask("ring-check-1", "Is the ring intact?")
    assert ring.value is True and ring.given == SCRIPT and len(term.asked) == 2  # nothing asked for it


def test_the_script_reports_what_the_plan_asked_and_rolls_the_simulated_barrel() -> None:
    rolled: list[tuple[float, int]] = []

    def hands(depth_in: float, passes: int) -> tuple[float, float]:
        rolled.append((depth_in, passes))
        return 1750.0, 3.0

    said = ScriptedRoller(rolled_by="A. Roller", hands=hands).roll("abi-roll-2", "Roll", 0.025, 4)
    assert rolled == [(0.025, 4)]
    assert (said.depth_in, said.passes, said.who, said.given) == (0.025, 4, "A. Roller", SCRIPT)
    assert (said.hoop_hz, said.hoop_u_hz) == (1750.0, 3.0)
    bare = ScriptedRoller().roll("abi-roll-1", "Roll", 0.0125, 4)  # a real rig's script: nobody rolls
    assert bare.who == "script" and bare.hoop_hz is None and bare.given == SCRIPT


@pytest.mark.parametrize(
    ("extra", "why"),
    [
        (
            ["--procedure", "bbcor", "--rolled-by", "A. Roller"],
            "--rolled-by goes with an accelerated break-in",
        ),
        (["--procedure", "abi", "--rolled-by", " "], "a name of 1-200 printable characters"),
    ],
)
def test_rolled_by_is_checked_before_the_run(
    extra: list[str], why: str, tmp_path: object, capsys: pytest.CaptureFixture[str]
) -> None:
    bat = str(Path(__file__).resolve().parents[2] / "protocols" / "examples" / "composite-bat.toml")
    db = f"{tmp_path}/r.db"
    assert main(["certify", *extra, "--bat", bat, "--sim", "composite", "--db", db]) == 2
    err = capsys.readouterr().err.strip()
    assert why in err and "\n" not in err
