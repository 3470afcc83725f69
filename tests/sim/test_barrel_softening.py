"""The composite barrel that rolling softens: the law against hand-computed values, the paper's
relation between wall stiffness, hoop frequency and squeeze, and the trampoline's rise."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.simulators.effects.softening import BarrelSofteningConfig, stiffness_after
from rig.simulators.scene import Scene
from rig.simulators.truth import true_metric
from rig.simulators.world import SimWorld

CONFIG = BarrelSofteningConfig()


def test_one_stage_by_hand() -> None:
    # 16 passes at 0.0125 in: dose 0.01 * 16 = 0.16; s = 0.55 + 0.45 exp(-0.16)
    assert stiffness_after(1.0, 0.0125, 16, CONFIG) == pytest.approx(0.55 + 0.45 * 0.8521437889662113)
    # twice as deep hurts four times as fast (p = 2): 2 passes at 0.025 in = 8 at 0.0125 in
    assert stiffness_after(1.0, 0.025, 4, CONFIG) == pytest.approx(stiffness_after(1.0, 0.0125, 16, CONFIG))


@given(
    s=st.floats(0.56, 1.0),
    depth=st.floats(0.0, 0.05),
    a=st.integers(0, 40),
    b=st.integers(0, 40),
)
def test_passes_add_and_the_barrel_never_softens_past_its_floor(
    s: float, depth: float, a: int, b: int
) -> None:
    once = stiffness_after(s, depth, a + b, CONFIG)
    twice = stiffness_after(stiffness_after(s, depth, a, CONFIG), depth, b, CONFIG)
    assert once == pytest.approx(twice, rel=1e-12)
    assert CONFIG.floor <= once <= s


def test_rolling_is_refused_with_a_negative_depth() -> None:
    with pytest.raises(ValueError, match="depth >= 0"):
        stiffness_after(1.0, -0.01, 3, CONFIG)


def test_a_rolled_barrel_falls_in_hoop_and_squeeze_as_the_model_says_and_its_bbcor_rises() -> None:
    scene = Scene.load("composite")
    sim = SimWorld(scene)
    barrel = sim.barrel
    assert barrel is not None
    f0, force0 = barrel.hoop_hz, barrel.true_force_lbf(0.04)
    truth0 = true_metric(scene, (6.0,)).value
    hoop = sim.roll(0.0125, 20)
    s = 0.55 + 0.45 * math.exp(-0.2)
    # the paper's hoop spring k2 = m2 (2 pi f)^2: f scales as sqrt(k2), the static squeeze as k2
    assert hoop == pytest.approx(f0 * math.sqrt(s))
    assert barrel.true_force_lbf(0.04) / force0 == pytest.approx((hoop / f0) ** 2)
    # the world's collision now uses the softer barrel: the same as a new bat built with that hoop
    softer = scene.with_bat(hoop_hz=hoop)
    truth1 = true_metric(softer, (6.0,)).value
    assert truth1 > truth0 + 0.002
    q = scene.bat.length_m - scene.rig.pivot_from_knob_m - 6.0 * 0.0254
    e_world, _ = sim.collision.collide(scene.ball, 60.8, q)
    e_new, _ = SimWorld(softer).collision.collide(scene.ball, 60.8, q)
    assert e_world == pytest.approx(e_new, rel=1e-12)


def test_a_scene_without_the_effect_cannot_be_rolled() -> None:
    with pytest.raises(ValueError, match="does not soften"):
        SimWorld(Scene.load("lab")).roll(0.0125, 3)
