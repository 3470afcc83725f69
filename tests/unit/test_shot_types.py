"""One name per shot concept: the simulator's truth, the raw record of a firing, the folded record."""

from __future__ import annotations

import ast
from pathlib import Path

import rig.simulators.records
from rig.simulators.records import ShotTruth
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld

ROOT = Path(__file__).resolve().parents[2]
# Every class whose name is a shot (not a shot's part: ShotInputs, ShotSpeeds, events, errors).
SHOT_TYPES = {
    "ShotTruth": "simulators/records.py",
    "ShotRecord": "protocols/shot.py",
    "ShotEntry": "rig/core/run_state.py",
    "LiveShot": "rig/tui/live.py",  # the console's view of a ShotEntry, not a record of its own
}


def _classes_named_shot() -> dict[str, str]:
    found = {}
    for package in ("rig", "protocols", "drivers", "simulators"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ClassDef) and node.name in {"Shot", *SHOT_TYPES}:
                    found[node.name] = str(path.relative_to(ROOT))
    return found


def test_each_shot_concept_has_one_name_and_no_class_is_a_bare_shot() -> None:
    assert _classes_named_shot() == SHOT_TYPES
    assert not hasattr(rig.simulators.records, "Shot")


def test_the_simulated_world_keeps_its_truth_as_shot_truth() -> None:
    world = SimWorld(Scene())
    truth = world.fire(400.0, 1)
    assert isinstance(truth, ShotTruth) and world.shots == [truth]
    assert truth.hit and 0.0 < truth.e_a < 1.0 and truth.impact_speed > 0.0
