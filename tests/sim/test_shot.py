"""A full shot at the byte level in the ideal scene: the gate ticks reproduce the closed forms."""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Callable

import pytest

from rig.drivers.gates.codec import elapsed_ticks, parse_config, parse_crossing
from rig.physics import DEFAULT_PARAMS, PivotedBat, predict_bat
from rig.simulators import physics
from rig.simulators.effects import KINDS, Effect
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig

P = 395.0
TICK_S = 100e-9
SPACING_M = 0.25


def crossings(events: list) -> list[tuple[int, int]]:
    return [(c.gate, c.tick) for c in (parse_crossing(e) for e in events)]


def test_ideal_shot_gives_six_events_matching_the_closed_forms(rig: Rig) -> None:
    cfg = parse_config(rig.gates.ok("CFG"))
    assert (cfg.gates, cfg.tick_ns, cfg.bits) == (3, 100.0, 32)
    q = 0.52
    got = crossings(rig.shot(P, position_mm=q * 1000))
    assert [g for g, _ in got] == [1, 2, 3, 3, 2, 1]
    t = [tick for _, tick in got]

    v_in = rig.world.scene.cannon.muzzle_speed(P)
    e_a = predict_bat(DEFAULT_PARAMS, v_in, None, PivotedBat(moi_kgm2=0.19, impact_from_pivot_m=q)).e_a
    v_out = e_a * v_in
    # Each difference of two rounded ticks is within one tick of the exact transit time.
    for a, b, speed in ((0, 1, v_in), (1, 2, v_in), (3, 4, v_out), (4, 5, v_out)):
        exact = SPACING_M / speed / TICK_S
        assert abs(elapsed_ticks(t[a], t[b], 32) - exact) <= 1.0
        measured = SPACING_M / (elapsed_ticks(t[a], t[b], 32) * TICK_S)
        assert measured == pytest.approx(speed, rel=1.0 / exact)
    truth = rig.world.shots[0]
    assert truth.launch_speed == v_in and truth.e_a == pytest.approx(e_a, rel=1e-12)


def test_gates_stream_only_while_armed_and_disarm_cancels_unread_breaks(rig: Rig) -> None:
    rig.prepare(P)
    rig.gates.ok("DISARM")
    rig.cannon.ok("ARM")
    rig.cannon.ok("FIRE")
    assert rig.gates.drain() == []
    rig.cannon.drain()
    rig.gates.ok("ARM")
    rig.cannon.ok("ARM")
    rig.cannon.ok("FIRE")
    rig.gates.ok("DISARM")  # before the ball reaches gate 1, in virtual time
    assert rig.gates.drain() == []
    assert len(rig.world.shots) == 2


def test_clock_counts_virtual_time_and_test_passes(rig: Rig) -> None:
    t0 = int(rig.gates.ok("CLOCK").named()["T"])
    rig.world.advance(1.5)
    t1 = int(rig.gates.ok("CLOCK").named()["T"])
    assert t1 - t0 == 15_000_000
    assert rig.gates.ok("TEST").named() == {"RESULT": "PASS"}


def test_counter_wrap_mid_shot() -> None:
    first = Rig(SimWorld(Scene()))
    plain = crossings(first.shot(P))
    start = (1 << 32) - plain[0][1] - 100  # gate 1 latches 100 ticks before the wrap
    wrapped_rig = Rig(SimWorld(Scene.model_validate({"rig": {"counter_start": start}})))
    wrapped = crossings(wrapped_rig.shot(P))
    assert wrapped[0][1] == (1 << 32) - 100 and wrapped[1][1] < wrapped[0][1]
    diffs = [elapsed_ticks(a[1], b[1], 32) for a, b in itertools.pairwise(wrapped)]
    assert diffs == [b[1] - a[1] for a, b in itertools.pairwise(plain)]


def _effect_classes() -> list[type[Effect]]:
    found, todo = [], [Effect]
    while todo:
        cls = todo.pop()
        found.append(cls)
        todo.extend(cls.__subclasses__())
    return found


@pytest.fixture
def spy(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    """Count every call of every method any effect class defines, constructors included."""
    calls: Counter[str] = Counter()

    def wrap(name: str, fn: Callable) -> Callable:
        def spied(*args: object, **kwargs: object) -> object:
            calls[name] += 1
            return fn(*args, **kwargs)

        return spied

    for cls in _effect_classes():
        for attr, fn in list(vars(cls).items()):
            if callable(fn) and (not attr.startswith("__") or attr == "__init__"):
                monkeypatch.setattr(cls, attr, wrap(f"{cls.__name__}.{attr}", fn))
    return calls


def _run_shots(scene: Scene, n: int = 3) -> SimWorld:
    rig = Rig(SimWorld(scene))
    for _ in range(n):
        rig.shot(P)
        rig.cannon.drain()
        rig.clamp.drain()
        rig.cannon.ok("ENV")
    return rig.world


def test_effects_left_out_are_never_called(spy: Counter[str], ideal: Scene) -> None:
    plain = _run_shots(ideal)
    assert sum(spy.values()) == 0
    # Listing every effect, each disabled, is the same as listing none.
    listed = Scene.model_validate({"effects": [{"kind": k, "enabled": False} for k in KINDS]})
    disabled = _run_shots(listed)
    assert sum(spy.values()) == 0
    assert [s.ticks for s in disabled.shots] == [s.ticks for s in plain.shots]
    _run_shots(Scene.load("lab"), n=1)  # the spy does see effects that are on
    assert spy["Drag.time_to"] > 0 and spy["Trampoline.collide"] == 1


def test_rigid_collision_is_solved_once(monkeypatch: pytest.MonkeyPatch, ideal: Scene) -> None:
    solves = []
    real = physics.predict_bat

    def counting(*args: object, **kwargs: object) -> object:
        solves.append(args[2])
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(physics, "predict_bat", counting)
    world = _run_shots(ideal, n=4)
    assert solves == [None]  # one rigid-barrel solve for four identical shots
    assert len({s.e_a for s in world.shots}) == 1


def test_a_ball_beyond_the_tip_misses_the_bat(rig: Rig) -> None:
    got = crossings(rig.shot(P, position_mm=800.0))  # tip is 686 mm from the pivot
    assert [g for g, _ in got] == [1, 2, 3]
    assert not rig.world.shots[0].hit


def test_a_slow_rebound_drops_below_the_far_gates(rig: Rig) -> None:
    # Near the tip e_A is small; the ball falls more than 5 cm before reaching gate 1.
    got = crossings(rig.shot(P, position_mm=680.0))
    assert [g for g, _ in got][:3] == [1, 2, 3] and 1 not in [g for g, _ in got][3:]
