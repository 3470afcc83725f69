"""docs/architecture.md's floors are the code's: computed from the imports, compared with the doc."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.floors import floors, group_of, table

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def test_the_documented_floors_are_the_imports() -> None:
    block = re.search(r"<!-- floors: begin.*?-->\n(.*?)\n<!-- floors: end -->", DOC.read_text(), re.S)
    assert block is not None, "docs/architecture.md has no floors table"
    assert block.group(1) == table(), "the floors changed: paste `python -m tests.floors` into the doc"


def test_a_floor_stands_only_on_lower_floors() -> None:
    floor = floors()
    assert floor["rig.core"] == 1 and floor["studies"] == max(floor.values())
    assert floor["rig.protocols"] < floor["rig.certification"] < floor["rig.cli"]


def test_groups_that_import_each_other_have_no_floor(monkeypatch: pytest.MonkeyPatch) -> None:
    import tests.floors as mod

    real = mod.grimp.build_graph

    def with_a_loop(*roots: str, **kw: object) -> object:
        graph = real(*roots, **kw)  # type: ignore[arg-type]
        graph.add_import(importer="rig.core.units", imported="rig.physics.params")
        return graph

    monkeypatch.setattr(mod.grimp, "build_graph", with_a_loop)
    with pytest.raises(ValueError, match="circle"):
        floors()
    assert group_of("rig.core.units") == "rig.core" and group_of("studies.cli") == "studies"
