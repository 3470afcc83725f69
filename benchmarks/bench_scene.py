"""Benchmark: wall time per simulated shot, ideal scene against each single effect and the lab.

Every figure is measured in this one run, rounds interleaved so that drift hits all rows alike;
each row shows its best round (interference from other processes only ever adds time).
Two timings per row: a full shot cycle at the byte level (PSET/READY, ARM, FIRE, every reply and
event framed, decoded and read back) and SimWorld.fire() alone (the physics of one shot). The
row "ideal + all effects listed, disabled" shows that an effect left out costs nothing: it must
match "ideal" within noise. Run: .venv/bin/python benchmarks/bench_scene.py [--shots N --rounds R]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from collections.abc import Callable

from rig.drivers.cannon.codec import SPECS as CANNON
from rig.drivers.codec import HostCodec
from rig.drivers.gates.codec import SPECS as GATES
from rig.physics import fast
from rig.simulators.effects import KINDS
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld

PRESSURE_KPA = 395.0


def cycle_runner(scene: Scene) -> Callable[[int], None]:
    """A world prepared for shots (grip locked, gates armed); returns a function firing n shots."""
    world = SimWorld(scene)
    cannon, gates = HostCodec(CANNON), HostCodec(GATES)
    clamp = world.clamp
    clamp.write(b"")  # nothing: the grip is closed through the world below
    world.set_interlock("clamp", True)
    world.gates.write(gates.command("ARM")[1])

    def command(verb: str, *args: object) -> None:
        world.cannon.write(cannon.command(verb, *args)[1])
        cannon.feed(world.cannon.read())

    def run(n: int) -> None:
        for _ in range(n):
            command("PSET", PRESSURE_KPA)
            command("ARM")
            command("FIRE")
            gates.feed(world.gates.read())
            world.clamp.read()
            cannon.feed(world.cannon.read())

    run(1)  # the first shot solves (and caches) the collision: not what a run of shots costs
    return run


def fire_runner(scene: Scene) -> Callable[[int], None]:
    """SimWorld.fire() alone, with the gates armed and the grip locked."""
    world = SimWorld(scene)
    world.gates.armed = True
    world.set_interlock("clamp", True)

    def run(n: int) -> None:
        for i in range(n):
            world.fire(PRESSURE_KPA, i + 1)
            world.gates.out.clear()
            world.clamp.out.clear()

    run(1)
    return run


def scenarios() -> dict[str, Scene]:
    """Ideal, ideal with everything listed but disabled, ideal plus each effect, lab."""
    out = {"ideal": Scene.load("ideal")}
    out["ideal + all effects listed, disabled"] = Scene.model_validate(
        {"effects": [{"kind": k, "enabled": False} for k in KINDS]}
    )
    for kind in KINDS:
        out[f"ideal + {kind}"] = Scene.model_validate({"effects": [{"kind": kind}]})
    out["lab"] = Scene.load("lab")
    return out


def per_shot(make: Callable[[Scene], Callable[[int], None]], scene: Scene, shots: int) -> float:
    """Seconds per shot over `shots` shots in a fresh world."""
    run = make(scene)
    t0 = time.perf_counter()
    run(shots)
    return (time.perf_counter() - t0) / shots


def main(argv: list[str] | None = None) -> int:
    """Measure and print the table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--shots", type=int, default=200, help="shots per world per round")
    parser.add_argument("--rounds", type=int, default=6, help="interleaved rounds; the best is shown")
    args = parser.parse_args(argv)
    fast.warm_up()
    scenes = scenarios()
    cycle: dict[str, list[float]] = {name: [] for name in scenes}
    fire: dict[str, list[float]] = {name: [] for name in scenes}
    for _ in range(args.rounds):
        for name, scene in scenes.items():
            cycle[name].append(per_shot(cycle_runner, scene, args.shots))
            fire[name].append(per_shot(fire_runner, scene, args.shots))
    med_cycle = {k: min(v) for k, v in cycle.items()}
    med_fire = {k: min(v) for k, v in fire.items()}
    # Noise yardstick: how far the same scene's best rounds sit apart when measured twice.
    halves = [abs(min(v[0::2]) - min(v[1::2])) / min(v) for v in cycle.values() if len(v) > 1]
    spread = statistics.median(halves) if halves else float("nan")
    base_c, base_f = med_cycle["ideal"], med_fire["ideal"]
    version = platform.python_version()
    print(f"# bench_scene: {args.shots} shots x {args.rounds} rounds, best round; python {version}")
    print(f"{'scene':42s} {'cycle us/shot':>14s} {'x ideal':>8s} {'fire() us':>10s} {'x ideal':>8s}")
    for name in scenes:
        c, f = med_cycle[name], med_fire[name]
        print(f"{name:42s} {c * 1e6:14.1f} {c / base_c:8.2f} {f * 1e6:10.1f} {f / base_f:8.2f}")
    print(f"# noise: best of even vs best of odd rounds differ by {spread:.1%} (median over rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
