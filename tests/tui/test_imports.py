"""The console's screens talk through Textual messages: no screen module imports another screen's.

Every import between rig.tui modules (also those inside functions) is read from the source; the
graph must have no cycle, and the set-up, run and history screens reach one another only by
posting messages the app handles (rig.tui.messages).
"""

from __future__ import annotations

import ast
from pathlib import Path

import rig.tui

TUI = Path(rig.tui.__file__).parent
SCREENS = {"rig.tui.setup", "rig.tui.run", "rig.tui.run_keys", "rig.tui.history"}


def _imports() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in sorted(TUI.glob("*.py")):
        name = f"rig.tui.{path.stem}"
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module == "rig.tui":
                found |= {f"rig.tui.{a.name}" for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("rig.tui."):
                found.add(node.module)
            elif isinstance(node, ast.Import):
                found |= {a.name for a in node.names if a.name.startswith("rig.tui.")}
        graph[name] = found - {name}
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> list[str] | None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*path, node, nxt]
            if nxt not in state and (found := visit(nxt, [*path, node])):
                return found
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (found := visit(start, [])):
            return found
    return None


def test_the_console_modules_import_no_cycle() -> None:
    assert _cycle(_imports()) is None


def test_screens_do_not_import_one_another() -> None:
    graph = _imports()
    own = ("rig.tui.run", "rig.tui.run_keys")  # run_keys is the run screen's own key mixin
    crossing = {(a, b) for a in SCREENS for b in graph[a] & SCREENS if (a, b) != own}
    assert crossing == set()
