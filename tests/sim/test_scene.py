"""Scenes: built-ins load, files override defaults, and a bad file names the file and the field."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from rig.core.errors import ConfigError
from rig.simulators.effects import KINDS
from rig.simulators.scene import Scene


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scene.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_builtins_load_with_their_names() -> None:
    assert Scene.builtin_names() == ["composite", "drag", "faulty", "ideal", "lab", "softball"]
    assert [e.kind for e in Scene.load("drag").effects] == ["drag"]  # drag only (finding 5)
    ideal, lab, faulty = Scene.load("ideal"), Scene.load("lab"), Scene.load("faulty")
    assert (ideal.name, lab.name, faulty.name) == ("ideal", "lab", "faulty")
    assert ideal.effects == ()
    assert {e.kind for e in lab.effects} == {
        "speed_scatter", "gate_timing", "drag", "trampoline", "recoil", "ball_wear", "environment",
    }  # fmt: skip
    composite = {e.kind for e in Scene.load("composite").effects}
    assert composite == {e.kind for e in lab.effects} | {"barrel_softening"}  # the lab, and a barrel to roll
    assert {e.kind for e in faulty.effects} >= {
        "misfire", "missed_trigger", "double_trigger", "garbled", "dropped_reply", "unplug", "interlock",
    }  # fmt: skip


def test_every_effect_kind_is_in_some_builtin() -> None:
    listed = {e.kind for name in Scene.builtin_names() for e in Scene.load(name).effects}
    assert listed == set(KINDS)


def test_defaults_are_the_rig_of_the_brief() -> None:
    scene = Scene()
    assert scene.rig.gate_positions_m == (0.75, 0.50, 0.25)
    assert (scene.rig.tick_ns, scene.rig.counter_bits, scene.rig.counter_start) == (100.0, 32, 0)
    assert scene.bat.moi_kgm2 == pytest.approx(0.19)
    assert scene.bat.length_m == pytest.approx(33 * 0.0254)
    # 60.8 m/s (136 mph) needs a few hundred kPa, and the inverse is exact.
    p = scene.cannon.pressure_for(60.8)
    assert 200.0 < p < 600.0
    assert scene.cannon.muzzle_speed(p) == pytest.approx(60.8, rel=1e-12)


def test_a_file_overrides_only_what_it_lists(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        """
        seed = 42
        [rig]
        gate_positions_m = [0.9, 0.6, 0.3]
        counter_start = 4294967000
        [bat]
        moi_kgm2 = 0.21
        [ball]
        c1 = 4800.0
        [[effects]]
        kind = "drag"
        drag_coefficient = 0.4
        """,
    )
    scene = Scene.load(path)
    assert scene.name == "scene" and scene.seed == 42
    assert scene.rig.gate_positions_m == (0.9, 0.6, 0.3) and scene.rig.tick_ns == 100.0
    assert scene.bat.moi_kgm2 == 0.21 and scene.bat.hoop_hz == 1800.0
    assert scene.ball.c1 == 4800.0 and scene.ball.m1 == 0.145
    assert scene.effects[0].drag_coefficient == 0.4  # type: ignore[union-attr]
    assert scene.rig_config_fragment()["gates"]["positions_m"] == (0.9, 0.6, 0.3)


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ("seed = ", "", "not valid TOML"),
        ('[[effects]]\nkind = "wormhole"\n', "effects.0", "wormhole"),
        (
            '[[effects]]\nkind = "drag"\ndrag_coefficient = -1.0\n',
            "effects.0.drag.drag_coefficient",
            "greater",
        ),
        ('[[effects]]\nkind = "drag"\ncd = 0.3\n', "effects.0.drag.cd", "not permitted"),
        ("[bat]\nweight_kg = 1.0\n", "bat.weight_kg", "not permitted"),
        ("[rig]\ntick_ns = 0\n", "rig.tick_ns", "greater"),
        ("[rig]\ngate_positions_m = [0.25, 0.5, 0.75]\n", "rig", "fall strictly"),
        ("[bat]\nmoi_kgm2 = 0.05\n", "(scene)", "m d^2"),
        ('[[effects]]\nkind = "drag"\n[[effects]]\nkind = "drag"\n', "(scene)", "flight"),
        ('[[effects]]\nkind = "misfire"\nshots = [0]\n', "effects.0.misfire.shots.0", "greater"),
    ],
)
def test_bad_file_names_file_and_field(tmp_path: Path, text: str, field: str, words: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        Scene.load(path)
    err = info.value
    assert err.source == str(path)
    assert err.field == field
    assert words in str(err)
    assert str(path) in str(err)


def test_a_disabled_effect_does_not_count_for_its_slot() -> None:
    scene = Scene.model_validate({"effects": [{"kind": "drag", "enabled": False}, {"kind": "drag"}]})
    assert len(scene.active_effects()) == 1


def test_unknown_scene_lists_the_builtins() -> None:
    with pytest.raises(ConfigError, match="built-in scenes: composite, drag, faulty, ideal, lab"):
        Scene.load("no-such-scene")


def _first_draws(scene: Scene) -> list[float]:
    """Each enabled effect's first random draw in a fresh world of `scene`."""
    from rig.simulators.world import SimWorld

    return [e.rng.random() for e in SimWorld(scene).effects]


def test_each_run_draws_its_own_noise_and_a_repeated_run_repeats_it() -> None:
    """Noise is a run's own (Scene.run_key): before, every bat of a population met the same speed
    scatter, timing jitter and sensor noise, so their errors did not average out over the bats."""
    lab = Scene.load("lab")
    a, b = lab.with_bat(id="BAT-A"), lab.with_bat(id="BAT-B")
    assert _first_draws(a) == _first_draws(a)  # the same run repeats
    pairs = zip(_first_draws(a), _first_draws(b), strict=True)
    assert all(x != y for x, y in pairs)  # another bat: every effect draws other numbers
    later = a.with_effect("environment", start_s=1200.0)  # a ball test at another hour
    assert all(x != y for x, y in zip(_first_draws(a), _first_draws(later), strict=True))
    plate = lab.with_target("plate")
    assert plate.run_key() != a.run_key() and plate.run_key().startswith(f"{lab.seed}/plate")


def test_a_session_or_a_nearby_hour_is_another_run() -> None:
    lab = Scene.load("lab").with_bat(id="BAT-A")
    again = lab.model_copy(update={"session": "store-run-1"})
    assert all(x != y for x, y in zip(_first_draws(lab), _first_draws(again), strict=True))
    near = [lab.with_effect("environment", start_s=s).run_key() for s in (100000.2, 100000.4)]
    assert near[0] != near[1]


@pytest.mark.parametrize(
    ("key", "cor", "diameter_in"), [("44/375", 0.44, 12.0), ("52/300", 0.52, 12.0), ("47/375", 0.47, 11.0)]
)
def test_a_softball_class_is_a_ball_of_its_cor_mass_and_size(
    key: str, cor: float, diameter_in: float
) -> None:
    """The class's COR on a rigid wall at 60 mph, solved by a separately written ODE (scipy solve_ivp on
    Eq. 1 with x2 = 0), its mass and the drag effect's diameter (circumference / pi)."""
    from scipy.integrate import solve_ivp

    scene = Scene.load("lab").with_ball_class(key)
    b = scene.ball
    assert scene.ball_class == key and b.m1 == pytest.approx(0.187)
    assert b.k1 == pytest.approx(6e7 * int(key[3:]) / 375)
    v0 = 60 * 0.44704

    def rhs(t: float, y: list[float]) -> list[float]:
        d, v = y  # compression and its rate (the ball's speed into the wall)
        f = b.k1 * abs(d) ** (1 + b.a) * (1 if d > 0 else -1) + b.c1 * v * abs(d) ** b.b
        return [v, -f / b.m1]

    def released(t: float, y: list[float]) -> float:  # the contact force falls to zero
        d, v = y
        return b.k1 * abs(d) ** (1 + b.a) + b.c1 * v * abs(d) ** b.b if t > 1e-6 else 1.0

    released.terminal, released.direction = True, -1  # type: ignore[attr-defined]
    sol = solve_ivp(rhs, (0.0, 0.01), [0.0, v0], events=released, rtol=1e-11, atol=1e-14, method="DOP853")
    assert -sol.y_events[0][0][1] / v0 == pytest.approx(cor, abs=2e-6)
    drag = next(e for e in scene.effects if e.kind == "drag")
    assert drag.ball_diameter_m == pytest.approx(diameter_in * 0.0254 / math.pi)


def test_the_softball_scene_fires_44_375_and_an_unknown_class_is_refused_in_one_line() -> None:
    soft = Scene.load("softball")
    assert soft.ball_class == "44/375" and soft.ball.m1 == pytest.approx(0.187)
    assert soft.with_ball_class("47/375").ball.c1 != soft.ball.c1
    assert (
        soft.with_ball_class("44/375") is soft and Scene.load("lab").with_ball_class(None).ball_class is None
    )
    with pytest.raises(ConfigError, match="no simulated softball of class '40/400'") as caught:
        Scene.load("lab").with_ball_class("40/400")
    assert "\n" not in str(caught.value)
