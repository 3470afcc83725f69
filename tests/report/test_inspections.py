"""Inspections are asked, not assumed (issue 24): the record keeps how each answer was given, and the
certificate counts a ring check as inspected only when it was answered on its own prompt.

Each run below is a BBCOR on the ideal simulated rig through the real drivers; the counts the
certificate prints are checked against the log's own OperatorAnswered entries, counted here.
"""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.protocols.control import ASKED, SCRIPT, WITH, Answer, ScriptedOperator
from rig.protocols.procedure import Procedure
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


class OneKeyOperator:
    """A person who answers the shot's review and lets that key pass the ring checks up to the next
    hit, as a lab's one key does: the ring checks after the first are given WITH the review."""

    who = "one-key operator"

    def __init__(self) -> None:
        self.review = ""

    def ask(self, prompt_id: str, text: str) -> Answer:
        if prompt_id.startswith("review-"):
            self.review = prompt_id
        elif prompt_id.startswith("ring-") and self.review:
            return Answer(True, WITH, self.review)
        elif not prompt_id.startswith("ring-"):
            self.review = ""
        return Answer(True, ASKED)


class BareOperator:
    """An API operator that answers with a bare bool: it does not say how."""

    who = "api operator"

    def ask(self, prompt_id: str, text: str) -> bool:
        return True


def _run(tmp_path: Path, operator: Any) -> tuple[list[dict[str, Any]], str]:
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(tmp_path / "r.db") as store:
        out = certify(
            store,
            Procedure.load("bbcor"),
            bat,
            sim_config("ideal", bat=bat),
            operator=operator,
            review_shots=True,
        )
        assert out.status == "finished"
        answered = [e.payload for e in store.entries(out.run_id, kinds=["OperatorAnswered"])]
        md = render(run_record(store, out.run_id), "md")
    return answered, md


def _row(md: str, prompt: str) -> list[str]:
    """The cells of the operator table's row for a prompt kind."""
    line = next(ln for ln in md.splitlines() if re.match(rf"\|\s*{re.escape(prompt)}\s*\|", ln))
    return [c.strip() for c in line.strip().strip("|").split("|")]


def test_a_scripted_run_records_every_answer_as_the_scripts(tmp_path: Path) -> None:
    answered, md = _run(tmp_path, ScriptedOperator(who="script (test)"))
    assert answered and {p["given"] for p in answered} == {SCRIPT}
    assert all("with_prompt" not in p for p in answered)
    rings = Counter(p["prompt_id"].rpartition("-")[0] for p in answered if p["prompt_id"].startswith("ring-"))
    head = _row(md, "prompt")
    assert head[3:6] == ["yes, on its own prompt", "yes, with another answer", "yes, by the script"]
    row = _row(md, "ring-before")
    assert row[3:6] == ["0", "0", str(rings["ring-before"])]  # none inspected by a person
    assert "nobody was shown the question" in md
    # and the first page's deviations say so, once, naming every ring check the script passed
    ring_ids = [p["prompt_id"] for p in answered if p["prompt_id"].startswith("ring-")]
    row = _row(md, f"{len(ring_ids)} ring checks answered by the script: nobody was shown them")
    assert row[2].split(", ") == ring_ids


def test_one_key_answers_are_recorded_with_the_acceptance_and_listed(tmp_path: Path) -> None:
    answered, md = _run(tmp_path, OneKeyOperator())
    rings = [p for p in answered if p["prompt_id"].startswith("ring-")]
    carried = [p for p in rings if p["given"] == WITH]
    own = [p for p in rings if p["given"] == ASKED]
    assert carried and own and len(carried) + len(own) == len(rings)
    assert all(p["with_prompt"].startswith("review-") for p in carried)
    by_kind: Counter[tuple[str, str]] = Counter(
        (p["prompt_id"].rpartition("-")[0], p["given"]) for p in rings
    )
    for kind in ("ring-before", "ring-after"):
        row = _row(md, kind)
        assert row[3:6] == [str(by_kind[kind, ASKED]), str(by_kind[kind, WITH]), "0"], row
    assert "Answers given with another prompt's answer" in md
    deviation = _row(
        md,
        f"{len(carried)} ring checks passed with another prompt's answer (the lab's one key), "
        "not on their own prompt",
    )
    assert deviation[2].split(", ") == [f"{p['prompt_id']} (with {p['with_prompt']})" for p in carried]
    for p in carried:  # each listed with the key that gave it
        assert re.search(rf"\|\s*{p['prompt_id']}\s*\|[^\n]*\|\s*{p['with_prompt']}\s*\|", md), p["prompt_id"]


def test_a_bare_answer_is_recorded_as_not_stated(tmp_path: Path) -> None:
    answered, md = _run(tmp_path, BareOperator())
    assert answered and all("given" not in p for p in answered)
    # the record does not say how: no split of the yes column is claimed for it
    assert "yes, on its own prompt" not in md and _row(md, "prompt")[3] == "yes"


def test_an_answer_says_how_it_was_given_consistently() -> None:
    with pytest.raises(ValueError, match="names that prompt"):
        Answer(True, WITH)
    with pytest.raises(ValueError, match="names that prompt"):
        Answer(True, ASKED, "review-1")
    with pytest.raises(ValueError, match="not 'guessed'"):
        Answer(True, "guessed")
