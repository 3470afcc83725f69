"""The lab's 'true' barrel: its own constants, a per-bat offset and an alteration (issue 10, 2)."""

from __future__ import annotations

import statistics
import subprocess
import sys

import pytest

from rig.drivers.gates.codec import elapsed_ticks, parse_crossing
from rig.physics import CollisionParams, PivotedBat, predict_bat
from rig.simulators.effects.trampoline import Trampoline, TrampolineConfig
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig

P = 395.0
LAB = Scene.load("lab")
LAB_TRAMPOLINE = next(e for e in LAB.effects if e.kind == "trampoline")


def true_scene(bat_id: str = "BAT-1", hoop_hz: float = 2000.0, **tramp: float) -> Scene:
    """The lab's barrel, noise on the gates and the cannon, straight flight (no drag, no wear)."""
    effects = [
        {"kind": "speed_scatter", "sigma_rel": 0.005},
        {"kind": "gate_timing", "jitter_ns": 20.0},
        {**LAB_TRAMPOLINE.model_dump(), **tramp},
    ]
    scene = Scene.model_validate({"seed": LAB.seed, "effects": effects})
    return scene.with_bat(id=bat_id, hoop_hz=hoop_hz)


def measured(scene: Scene, shots: int = 3) -> list[tuple[float, float, float]]:
    """(v_in, v_out, q) of shots at the sweet spot, from the gates' ticks (gates 2 and 3)."""
    world = SimWorld(scene)
    tramp = world.collision
    assert isinstance(tramp, Trampoline)
    rig, tick = Rig(world), scene.rig.tick_ns * 1e-9
    spacing = scene.rig.gate_positions_m[1] - scene.rig.gate_positions_m[2]
    out = []
    for _ in range(shots):
        got = [(c.gate, c.tick) for c in map(parse_crossing, rig.shot(P, tramp.sweet_spot_m * 1000))]
        rig.cannon.drain()
        rig.clamp.drain()
        ticks = [t for _, t in got]
        assert [g for g, _ in got] == [1, 2, 3, 3, 2, 1]
        v_in = spacing / (elapsed_ticks(ticks[1], ticks[2], 32) * tick)
        v_out = spacing / (elapsed_ticks(ticks[3], ticks[4], 32) * tick)
        out.append((v_in, v_out, tramp.sweet_spot_m))
    return out


def bbcor(e_a: float, q: float, moi: float, m_ball: float = 0.145) -> float:
    k = m_ball * q * q / moi
    return e_a * (1 + k) + k


def test_lab_barrel_is_its_own_not_the_papers() -> None:
    c = LAB_TRAMPOLINE
    assert isinstance(c, TrampolineConfig)
    paper = CollisionParams()
    assert c.m2 is not None and c.c2 is not None
    assert abs(c.m2 - paper.m2) > 0.05 and abs(c.c2 - paper.c2) > 50 and c.k1_scale != 1.0
    assert 0.003 <= c.spread_bbcor <= 0.007 and c.alteration_bbcor == 0.0


def test_measured_e_a_at_the_sweet_spot_is_the_model_with_the_scene_true_constants() -> None:
    scene = true_scene(spread_bbcor=0.0, hoop_hz=1800.0)
    c = LAB_TRAMPOLINE
    # independent of the effect: the ball constants written out, the true barrel put in by hand
    true = CollisionParams(m1=0.145, k1=6e7 * c.k1_scale, c1=5000.0, a=0.6495, b=0.5202, m2=c.m2, c2=c.c2)
    paper = CollisionParams(m1=0.145)
    for v_in, v_out, q in measured(scene):
        bat = PivotedBat(moi_kgm2=scene.bat.moi_kgm2, impact_from_pivot_m=q)
        expected = predict_bat(true, v_in, 1800.0, bat).e_a
        # the gates' 100 ns tick over 0.25 m: e_A to about 3e-5; the stage position rounds to 1 um
        assert v_out / v_in == pytest.approx(expected, abs=2e-4)
        assert abs(predict_bat(paper, v_in, 1800.0, bat).e_a - expected) > 0.02  # the test can tell


def test_the_bat_offset_is_fixed_per_bat_across_worlds_and_processes() -> None:
    def offset(bat_id: str) -> float:
        tramp = SimWorld(true_scene(bat_id)).collision
        assert isinstance(tramp, Trampoline)
        return tramp.offset_bbcor

    a1, a2, b = offset("BAT-A"), offset("BAT-A"), offset("BAT-B")
    assert a1 == a2 and a1 != b and a1 != 0.0
    code = (
        "from rig.simulators.scene import Scene; from rig.simulators.world import SimWorld;"
        "import tests.sim.test_population_scene as t;"
        "print(repr(SimWorld(t.true_scene('BAT-A')).collision.offset_bbcor))"
    )
    other = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env={"PYTHONHASHSEED": "7"}
    )
    assert float(other.stdout) == a1
    # the stated spread is the bats' standard deviation in BBCOR
    offsets = [offset(f"BAT-{i}") for i in range(300)]
    assert statistics.stdev(offsets) == pytest.approx(LAB_TRAMPOLINE.spread_bbcor, rel=0.15)
    assert abs(statistics.fmean(offsets)) < 3 * LAB_TRAMPOLINE.spread_bbcor / 300**0.5


def test_the_offset_and_an_alteration_raise_the_measured_bbcor_by_their_amount() -> None:
    legal = measured(true_scene("BAT-C", spread_bbcor=0.0))
    spread = measured(true_scene("BAT-C"))
    altered = measured(true_scene("BAT-C", alteration_bbcor=0.025))
    tramp = SimWorld(true_scene("BAT-C")).collision
    assert isinstance(tramp, Trampoline)
    moi = LAB.bat.moi_kgm2

    def mean_bbcor(rows: list[tuple[float, float, float]]) -> float:
        return statistics.fmean(bbcor(v_out / v_in, q, moi) for v_in, v_out, q in rows)

    # the same seed gives the same launch scatter, so the noise nearly cancels in the difference
    assert mean_bbcor(spread) - mean_bbcor(legal) == pytest.approx(tramp.offset_bbcor, abs=3e-4)
    assert mean_bbcor(altered) - mean_bbcor(spread) == pytest.approx(0.025, abs=3e-4)


def test_scenes_without_the_new_keys_keep_the_papers_barrel() -> None:
    old = Scene.model_validate({"effects": [{"kind": "trampoline"}]})
    tramp = SimWorld(old).collision
    assert isinstance(tramp, Trampoline) and tramp.offset_bbcor == 0.0
    params = old.ball
    assert tramp.barrel(params) is params


def test_an_effect_changed_before_the_bat_still_takes_the_bat() -> None:
    """with_effect / with_alteration, then with_bat: the bat's properties still arrive (they were
    silently the scene's default bat before, since a full dump marked every bat field as set)."""
    from rig.simulators.scene import Scene

    lab = Scene.load("lab")
    changed = lab.with_effect("trampoline", spread_bbcor=0.008).with_bat(hoop_hz=2500.0, moi_kgm2=0.2)
    assert changed.bat.hoop_hz == 2500.0 and changed.bat.moi_kgm2 == 0.2
    assert next(e for e in changed.effects if e.kind == "trampoline").spread_bbcor == 0.008
    altered = lab.with_alteration(0.02).with_bat(hoop_hz=2100.0)
    assert altered.bat.hoop_hz == 2100.0
