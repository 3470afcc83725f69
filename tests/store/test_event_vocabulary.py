"""No event kind (nor a verdict) is spelled as a string outside rig/core/events.py and the records its
events carry (rig/core/outcomes.py: the verdict enum lives there): the product code names kinds through
those modules (tests may spell them where they check the log's wire format)."""

from __future__ import annotations

import ast
from pathlib import Path

from rig.core import events as ev

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("rig", "protocols", "drivers", "simulators")
HOME = (ROOT / "rig" / "core" / "events.py", ROOT / "rig" / "core" / "outcomes.py")


KINDS = frozenset(ev.BY_KIND)
VERDICTS = frozenset(v.value for v in ev.Verdict)  # the gates' self-test also says PASS: drivers may


def spelled_kinds(path: Path, words: frozenset[str] = KINDS | VERDICTS) -> list[str]:
    """`file:line word` for each string constant in `path` that is exactly one of `words`."""
    tree = ast.parse(path.read_text(), str(path))
    name = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path.name
    hits = [
        (node.lineno, node.col_offset, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in words
    ]
    return [f"{name}:{line} {value}" for line, _, value in sorted(hits)]


def test_the_checker_finds_a_spelled_kind(tmp_path: Path) -> None:
    probe = tmp_path / "probe.py"
    probe.write_text('KINDS = ["ShotMeasured"]\nOK = "ShotMeasured is a kind"\nV = {"x": "PASS"}\n')
    assert spelled_kinds(probe) == ["probe.py:1 ShotMeasured", "probe.py:3 PASS"]


def test_no_event_kind_or_verdict_is_spelled_outside_the_event_module() -> None:
    found = [
        hit
        for package in PACKAGES
        for path in sorted((ROOT / package).rglob("*.py"))
        if path not in HOME
        for hit in spelled_kinds(path, KINDS | VERDICTS if package in ("rig", "protocols") else KINDS)
    ]
    assert found == []
