"""Constants with one home: the rig's pivot is 6 in from the knob (ASTM F2398), written once.

The value is the standard's; every model that places the pivot must take it from
rig.core.bat rather than restate it, so the source is scanned for a restated pivot.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rig.core.bat import PIVOT_FROM_KNOB_IN, PIVOT_FROM_KNOB_M
from rig.measure.metrics import SwingModel
from rig.simulators.scene import RigGeometry

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("rig", "protocols", "simulators", "drivers")
HOME = ROOT / "rig" / "core" / "bat.py"
# a pivot named on the line together with 6 in, written as a number: 6.0, 6 * INCH, 0.1524 m
RESTATED = re.compile(r"\b(6(\.0*)?\s*\*\s*INCH|0\.1524\d*|152\.4)\b|=\s*6(\.0*)?\b")


def test_the_pivot_is_the_standards_six_inches() -> None:
    assert PIVOT_FROM_KNOB_IN == 6.0
    assert abs(PIVOT_FROM_KNOB_M - 0.1524) < 1e-12  # 6 x 25.4 mm


def test_every_model_of_the_rig_places_the_pivot_at_the_one_constant() -> None:
    assert SwingModel().rig_pivot_from_knob_m == PIVOT_FROM_KNOB_M
    assert RigGeometry().pivot_from_knob_m == PIVOT_FROM_KNOB_M


def test_no_module_restates_the_pivot() -> None:
    """A line naming the rig's pivot (the BESR swing's own centre is another quantity), or the line
    after it, must not carry 6 in as a number."""
    restated = []
    for package in PRODUCT:
        for path in sorted((ROOT / package).rglob("*.py")):
            lines = path.read_text().splitlines()
            for n, line in enumerate(lines):
                if path == HOME or "pivot" not in line.lower() or "swing" in line.lower():
                    continue
                if RESTATED.search(" ".join(lines[n : n + 2])):
                    restated.append(f"{path.relative_to(ROOT)}:{n + 1}: {line.strip()}")
    assert restated == []


def test_the_stage_range_has_one_home() -> None:
    """The clamp stage's 100-900 mm: the wire codec, the plan's location check and the dry run's
    fakes all take it from rig.core.devices (a stage range written as numbers elsewhere fails)."""
    from rig.core.bat import BatSpec
    from rig.core.devices import STAGE_RANGE_MM
    from rig.drivers.clamp.codec import SPECS, STAGE_MAX_MM, STAGE_MIN_MM
    from rig.protocols.steps import location_problem

    assert (STAGE_MIN_MM, STAGE_MAX_MM) == STAGE_RANGE_MM == (100.0, 900.0)
    move = SPECS["MOVE"]
    assert move.check(900.0) == ("900.0",) or move.check(900.0)
    for outside in (99.9, 900.1):
        with pytest.raises(ValueError, match="outside"):
            move.check(outside)
    bat = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")  # 33 in: 5 in is 558.8 mm
    assert location_problem(bat, 5.0) is None
    restated = [
        str(p.relative_to(ROOT))
        for package in PRODUCT
        for p in sorted((ROOT / package).rglob("*.py"))
        if re.search(r"\b100(\.0)?\b.{0,40}\b900(\.0)?\b", p.read_text(), re.S)
        and p != ROOT / "rig/core/devices.py"
    ]
    assert restated == []
