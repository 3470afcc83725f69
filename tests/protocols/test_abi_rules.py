"""The ABI's rules: by hand, then on the simulated composite barrel (compression over the wire from the
tester's twin, the rolling done by a simulated operator on the world, BBCOR the simulator's truth)."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import pytest

from rig.core.config import DeviceSpec, Timeouts
from rig.drivers.registry import DriverContext, open_device
from rig.drivers.scpi.compression import ScpiCompressionTester
from rig.protocols.abi_rules import (
    AbiRules,
    Compressed,
    Inspected,
    Measured,
    Recorded,
    Rolled,
    next_step,
    stages,
)
from rig.simulators.effects.softening import stiffness_after
from rig.simulators.instruments.compression_tester import CompressionTesterTwin
from rig.simulators.scene import Scene
from rig.simulators.truth import true_metric
from rig.simulators.world import SimWorld

RULES = AbiRules.load()
LIMIT = 0.500


def test_the_built_in_file_says_the_ncaa_numbers() -> None:
    assert (RULES.location_in, RULES.stage_drop, RULES.broken_in_drop, RULES.depth_step_in) == (
        6.0,
        0.05,
        0.15,
        0.0125,
    )


def test_the_new_bat_then_a_stage_by_hand() -> None:
    h: list[Recorded] = []
    assert next_step(h, RULES, LIMIT).action == "compress"
    h.append(Compressed(240.0))
    assert next_step(h, RULES, LIMIT).action == "bbcor"
    h.append(Measured(0.480, 0.004))
    assert next_step(h, RULES, LIMIT).action == "inspect"
    h.append(Inspected(False))
    assert next_step(h, RULES, LIMIT).action == "compress"  # the stage's own start
    h.append(Compressed(239.0))
    step = next_step(h, RULES, LIMIT)
    assert (step.action, step.depth_in, step.passes) == ("roll", 0.0125, 4)
    h.append(Rolled(0.0125, 4, "pat"))
    assert next_step(h, RULES, LIMIT).action == "compress"
    h.append(Compressed(229.0))  # 4.2 % below the stage's start: not yet 5 %
    step = next_step(h, RULES, LIMIT)
    assert (step.action, step.depth_in) == ("roll", 0.025)  # one step deeper
    h += [Rolled(0.025, 4, "pat"), Compressed(227.0)]  # 5.02 % below 239
    assert next_step(h, RULES, LIMIT).action == "bbcor"
    h += [Measured(0.495, 0.004), Inspected(False)]
    assert next_step(h, RULES, LIMIT).action == "compress"


@pytest.mark.parametrize(
    ("last", "said"),
    [
        ([Measured(0.503, 0.004), Inspected(False)], "exceeds the limit"),
        ([Measured(0.490, 0.004), Inspected(True)], "shows damage"),
    ],
)
def test_the_abi_ends_over_the_limit_or_damaged(last: list[Recorded], said: str) -> None:
    h: list[Recorded] = [Compressed(240.0), Measured(0.48, 0.004), Inspected(False)]
    h += [Compressed(240.0), Rolled(0.0125, 4, "pat"), Compressed(220.0), *last]
    step = next_step(h, RULES, LIMIT)
    assert step.action == "end" and said in step.reason


def test_no_rolling_past_fifteen_percent_then_the_end() -> None:
    h: list[Recorded] = [Compressed(240.0), Measured(0.48, 0.004), Inspected(False)]
    h += [
        Compressed(240.0),
        Rolled(0.0125, 4, "pat"),
        Compressed(200.0),
        Measured(0.49, 0.004),
        Inspected(False),
    ]
    h.append(Compressed(200.0))  # 16.7 % below the new bat's 240
    step = next_step(h, RULES, LIMIT)
    assert step.action == "bbcor" and "16.7 %" in step.reason
    h += [Measured(0.492, 0.004), Inspected(False)]
    assert next_step(h, RULES, LIMIT).action == "end"


# -- on the simulated composite barrel -------------------------------------------------------------
@pytest.fixture
def lab() -> Iterator[tuple[SimWorld, ScpiCompressionTester]]:
    world = SimWorld(Scene.load("composite"))
    twin = CompressionTesterTwin(world)
    twin.start()
    context = DriverContext("compression", "compression", twin.address, {}, Timeouts(reply_s=10.0))
    tester = open_device("compression", context, DeviceSpec(**twin.device_table()))
    yield world, tester
    tester.close()
    twin.close()


def run_abi(world: SimWorld, tester: ScpiCompressionTester, limit: float) -> tuple[list[Recorded], str]:
    """The rules driven to their end: BC over the wire, rolling by a simulated operator, BBCOR the
    simulated truth at the BC location (the certified run through the gates is not wired yet)."""
    scene, barrel = world.scene, world.barrel
    assert barrel is not None
    history: list[Recorded] = []
    for _ in range(200):
        step = next_step(history, RULES, limit)
        if step.action == "end":
            return history, step.reason
        if step.action == "compress":
            history.append(Compressed(tester.measure_compression().force_lbf))
        elif step.action == "roll":
            world.roll(step.depth_in, step.passes)
            history.append(Rolled(step.depth_in, step.passes, "simulated operator"))
        elif step.action == "bbcor":
            truth = true_metric(scene.with_bat(hoop_hz=barrel.hoop_hz), (RULES.location_in,))
            history.append(Measured(truth.value, 0.0, barrel.hoop_hz))
        else:
            history.append(Inspected(barrel.damaged))
    raise AssertionError("the ABI did not end")


def test_a_composite_bat_breaks_in_over_two_or_more_stages(
    lab: tuple[SimWorld, ScpiCompressionTester],
) -> None:
    world, tester = lab
    barrel = world.barrel
    assert barrel is not None
    history, reason = run_abi(world, tester, LIMIT)
    cut = stages(history)
    rolled_stages = [s for s in cut if any(isinstance(x, Rolled) for x in s)]
    assert len(rolled_stages) >= 2, (history, reason)
    # the new bat, then each rolled stage: its hoop falls and its BBCOR rises
    measured = [x for s in [cut[0], *rolled_stages] for x in s if isinstance(x, Measured)]
    hoops = [m.hoop_hz or 0.0 for m in measured]
    assert all(b < a for a, b in itertools.pairwise(hoops))
    assert all(b.bbcor > a.bbcor for a, b in itertools.pairwise(measured))
    # ... by what the barrel's truth says: f0 sqrt(s) after the rollings recorded, s by the law
    s = 1.0
    for stage, m in zip([cut[0], *rolled_stages], measured, strict=True):
        for x in (x for x in stage if isinstance(x, Rolled)):
            s = stiffness_after(s, x.depth_in, x.passes, barrel.config)
        assert m.hoop_hz == pytest.approx(barrel.new_hoop_hz * s**0.5, rel=1e-12)
    # the compressions over the wire follow K0 s delta within the load cell's noise
    readings = [x.force_lbf for x in history if isinstance(x, Compressed)]
    assert readings[-1] == pytest.approx(barrel.true_force_lbf(0.040), abs=5 * barrel.config.noise_lbf)
    assert reason


def test_the_rules_resume_from_any_point_of_the_record(lab: tuple[SimWorld, ScpiCompressionTester]) -> None:
    world, tester = lab
    history, _ = run_abi(world, tester, LIMIT)
    replay = [next_step(history[:i], RULES, LIMIT).action for i in range(len(history))]
    kinds = {Compressed: "compress", Rolled: "roll", Measured: "bbcor", Inspected: "inspect"}
    assert replay == [kinds[type(x)] for x in history]
