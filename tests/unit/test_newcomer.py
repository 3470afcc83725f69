"""What a newcomer meets first: the README's quick start and the `make demo` that it runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _section(title: str) -> str:
    """The README's `## title` section."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## )", text, flags=re.S | re.M)
    assert match, title
    return match.group(1)


def _recipe(target: str) -> str:
    """The Makefile's recipe lines for `target`."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    match = re.search(rf"^{target}:.*\n((?:\t.*\n|\n)*)", text, flags=re.M)
    assert match, target
    return match.group(1)


def test_the_quick_start_says_how_to_run_rig_after_make_demo() -> None:
    """`rig` lives in .venv/bin, which is not on PATH: the README and the demo's last lines say how to
    run it, and that the demo's records are in out/demo.db (a bare `rig runs` reads rig-records.db)."""
    quick = _section("Quick start")
    assert ". .venv/bin/activate" in quick and ".venv/bin/rig" in quick
    assert "rig runs --db out/demo.db" in quick
    said = " ".join(line for line in _recipe("demo").splitlines() if "echo" in line)
    assert ". .venv/bin/activate" in said and "rig runs --db out/demo.db" in said
