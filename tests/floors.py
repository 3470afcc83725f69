"""The floors of the product's import graph, as docs/architecture.md shows them.

A group is a package folder (rig.core, protocols, ...) or a module directly under rig; a group's
floor is one above the highest group it imports (floor 1 imports no other group). Built from the
code's own imports (grimp, which import-linter uses), so the document cannot drift from the code.
"""

from __future__ import annotations

import grimp

ROOTS = ("rig", "studies")
SHOWN = {"rig.drivers": "drivers/", "rig.protocols": "protocols/", "rig.simulators": "simulators/"}


def group_of(module: str) -> str:
    """The group a module belongs to: its package under rig (or studies), or rig's root."""
    parts = module.split(".")
    if parts[0] == "studies":
        return "studies"
    return ".".join(parts[:2]) if len(parts) > 1 else "rig"


def imports() -> grimp.ImportGraph:
    """The import graph of our packages (grimp, as import-linter reads it)."""
    return grimp.build_graph(*ROOTS, include_external_packages=False)


def floors(graph: grimp.ImportGraph | None = None) -> dict[str, int]:
    """Each group's floor; a ValueError names groups that import each other (no floor exists)."""
    graph = graph or imports()
    deps: dict[str, set[str]] = {}
    for module in graph.modules:
        g = group_of(module)
        deps.setdefault(g, set()).update(
            group_of(m) for m in graph.find_modules_directly_imported_by(module) if group_of(m) != g
        )
    floor: dict[str, int] = {}
    while len(floor) < len(deps):
        ready = [g for g in deps if g not in floor and deps[g] <= floor.keys()]
        if not ready:
            raise ValueError(f"groups in a circle: {sorted(set(deps) - floor.keys())}")
        for g in ready:
            floor[g] = 1 + max((floor[d] for d in deps[g]), default=0)
    return floor


def name(group: str, packages: set[str]) -> str:
    """How the document names a group: a folder with a slash, a module as its file."""
    if group in SHOWN:
        return f"`{SHOWN[group]}`"
    if group == "rig":
        return "`rig/__init__.py`"
    path = group.replace(".", "/")
    return f"`{path}/`" if group in packages else f"`{path}.py`"


def table() -> str:
    """The floors as a Markdown table, top floor first."""
    graph = imports()
    packages = {group_of(m) for m in graph.modules if group_of(m) != m}
    by_floor: dict[int, list[str]] = {}
    for g, f in floors(graph).items():
        by_floor.setdefault(f, []).append(g)
    rows = ["| floor | groups (a floor imports only the floors below it) |", "|---|---|"]
    rows += [
        f"| {f} | {', '.join(name(g, packages) for g in sorted(by_floor[f]))} |"
        for f in sorted(by_floor, reverse=True)
    ]
    return "\n".join(rows)


if __name__ == "__main__":  # python -m tests.floors: the table docs/architecture.md shows
    print(table())
