"""Each physical effect against its stated model; scenes with effects are repeatable by seed."""

from __future__ import annotations

import math
import statistics

import pytest

from rig.drivers.cannon.codec import parse_environment
from rig.drivers.gates.codec import elapsed_ticks, parse_crossing
from rig.simulators.effects.drag import Drag
from rig.simulators.effects.environment import LabEnvironment
from rig.simulators.effects.trampoline import Trampoline
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig

P = 395.0


def scene_with(*effects: dict, seed: int = 0) -> Scene:
    return Scene.model_validate({"seed": seed, "effects": list(effects)})


def shots(scene: Scene, n: int, position_mm: float | None = None) -> SimWorld:
    rig = Rig(SimWorld(scene))
    for _ in range(n):
        rig.shot(P, position_mm)
        rig.cannon.drain()
        rig.clamp.drain()
    return rig.world


def test_trampoline_location_scan_has_one_maximum_near_the_sweet_spot() -> None:
    world = SimWorld(scene_with({"kind": "trampoline"}))
    tramp = world.collision
    assert isinstance(tramp, Trampoline)
    params, moi = world.scene.ball, world.scene.bat.moi_kgm2
    qs = [0.38 + 0.02 * i for i in range(15)]  # 0.38 .. 0.66 m from the pivot
    bbcor = []
    for q in qs:
        e_a, _ = tramp.collide(params, 60.8, q)
        k = params.m1 * q * q / moi
        bbcor.append(e_a * (1 + k) + k)
    best = max(range(len(qs)), key=bbcor.__getitem__)
    assert 0 < best < len(qs) - 1
    assert abs(qs[best] - tramp.sweet_spot_m) <= 0.03
    rigid, _ = SimWorld(Scene()).collision.collide(params, 60.8, tramp.sweet_spot_m)
    assert tramp.collide(params, 60.8, tramp.sweet_spot_m)[0] > rigid + 0.05


def test_drag_closed_form_is_consistent_and_slows_the_ball() -> None:
    world = SimWorld(scene_with({"kind": "drag"}))
    drag = world.flight
    assert isinstance(drag, Drag) and 150.0 < drag.length_m < 175.0
    v0, x = 60.8, 1.5
    t = drag.time_to(x, v0)
    # Quadratic drag: v(t) = v0 / (1 + v0 t / L) must equal v(x) = v0 exp(-x / L).
    assert drag.speed_at(x, v0) == pytest.approx(v0 / (1 + v0 * t / drag.length_m), rel=1e-12)
    assert t > x / v0
    rig = Rig(world)
    ticks = [parse_crossing(e).tick for e in rig.shot(P)]
    in12, in23 = elapsed_ticks(ticks[0], ticks[1], 32), elapsed_ticks(ticks[1], ticks[2], 32)
    assert in23 > in12  # slower on the second leg
    assert in23 / in12 == pytest.approx(math.exp(0.25 / drag.length_m), rel=2e-4)


def test_gate_timing_shifts_ticks_by_latency_and_jitter_only() -> None:
    timing = {"kind": "gate_timing", "jitter_ns": 20.0, "latency_ns": [0.0, 500.0, 0.0]}
    exact = shots(Scene(), 1).shots[0].ticks
    noisy = shots(scene_with(timing, seed=3), 1).shots[0].ticks
    offsets = [b[1] - a[1] for a, b in zip(exact, noisy, strict=True)]
    assert offsets[1] in (4, 5, 6) and offsets[4] in (4, 5, 6)  # gate 2 latches 500 ns late
    assert all(abs(o) <= 2 for i, o in enumerate(offsets) if i not in (1, 4))
    assert shots(scene_with(timing, seed=3), 1).shots[0].ticks == noisy


def test_speed_scatter_spreads_the_launch_speed() -> None:
    world = shots(scene_with({"kind": "speed_scatter", "sigma_rel": 0.01}, seed=5), 30)
    nominal = world.scene.cannon.muzzle_speed(P)
    rel = [s.launch_speed / nominal - 1 for s in world.shots]
    assert 0.005 < statistics.stdev(rel) < 0.02
    assert abs(statistics.mean(rel)) < 0.006


def test_ball_wear_lowers_the_cor_hit_by_hit() -> None:
    world = shots(scene_with({"kind": "ball_wear", "damping_per_hit": 0.01}), 4)
    e = [s.e_a for s in world.shots]
    assert e[0] == pytest.approx(shots(Scene(), 1).shots[0].e_a, rel=1e-12)
    assert e[0] > e[1] > e[2] > e[3]


def test_environment_readings_drift_and_warm_dry_balls_are_livelier() -> None:
    scene = scene_with({"kind": "environment", "temp_swing_c": 3.0, "period_s": 100.0}, seed=9)
    rig = Rig(SimWorld(scene))
    readings = []
    for _ in range(5):
        env = parse_environment(rig.cannon.ok("ENV"))
        readings.append((env.temperature_c, env.humidity_pct))
        rig.world.advance(10.0)
    assert len(set(readings)) == 5
    assert all(17.0 < t < 25.0 and 40.0 < rh < 60.0 for t, rh in readings)
    lab = rig.world.lab
    assert isinstance(lab, LabEnvironment)
    ball = scene.ball
    warm, cool = lab.ball_params(ball, 25.0), lab.ball_params(ball, 75.0)  # sin peak and trough
    assert warm.c1 < ball.c1 < cool.c1


def test_lab_scene_is_repeatable_and_seed_dependent() -> None:
    lab = Scene.load("lab")
    a, b = shots(lab, 3, 520.0), shots(lab, 3, 520.0)
    assert [s.ticks for s in a.shots] == [s.ticks for s in b.shots]
    other = shots(lab.model_copy(update={"seed": lab.seed + 1}), 3, 520.0)
    assert [s.ticks for s in other.shots] != [s.ticks for s in a.shots]
    assert all(s.recoil_rad_s and s.recoil_rad_s > 0 for s in a.shots)
