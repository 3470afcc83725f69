"""Benchmark: a simulated population certified on the lab scene (`rig-study population --certify N`).

Prints the wall time per certification and the scatter of each certified BBCOR about the scene's
true model, solved independently with rig.physics: the rigid and the flexible barrel with the
scene's own m2, c2 and k1 scale at the bat's certified location and true MOI, blended by the
location weight, plus (or not) the bat's own offset. The first scatter is the measurement noise a
cross-check must allow for; the second adds the bat-to-bat spread.

    python benchmarks/bench_simpop.py [--n 20] [--seed 0] [--altered 0]
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

from rig.core.units import INCH
from rig.physics import PivotedBat, predict_bat
from rig.simulators.effects.trampoline import TrampolineConfig, bat_offset_bbcor
from rig.simulators.scene import Scene
from rig.store import Store
from studies.cli import main
from studies.population.simulated import simulated_population

SPEED = 60.8


def true_bbcor(scene: Scene, hoop: float, moi: float, length_in: float, location_in: float) -> float:
    """The scene's true BBCOR (no per-bat offset) at this location, from rig.physics directly."""
    t = next(e for e in scene.effects if isinstance(e, TrampolineConfig))
    assert t.m2 is not None and t.c2 is not None
    params = scene.ball.model_copy(update={"m2": t.m2, "c2": t.c2, "k1": scene.ball.k1 * t.k1_scale})
    q = (length_in - location_in) * INCH - scene.rig.pivot_from_knob_m
    bat = PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)
    e_r = predict_bat(params, SPEED, None, bat).e_a
    e_h = predict_bat(params, SPEED, hoop, bat).e_a
    q_s = length_in * INCH - t.sweet_spot_from_tip_m - scene.rig.pivot_from_knob_m
    w = math.exp(-0.5 * ((q - q_s) / t.width_m) ** 2)
    k = params.m1 * q * q / moi
    e = e_r + w * (e_h - e_r) - t.off_node_loss_bbcor * (1 - w) / (1 + k)  # bending loss off the sweet spot
    return e * (1 + k) + k


def run(n: int, seed: int, altered: int) -> None:
    """Certify n bats into a temporary store, then compare with the true model."""
    scene = Scene.load("lab")
    tramp = next(e for e in scene.effects if isinstance(e, TrampolineConfig))
    bats = {b.spec.id: b for b in simulated_population(n, seed, altered)}
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "pop.db"
        t0 = time.perf_counter()
        flags = ["--certify", str(n), "--db", str(db), "--seed", str(seed), "--altered", str(altered)]
        code = main(["population", *flags])
        wall = time.perf_counter() - t0
        assert code == 0, code
        noise, total = [], []
        with Store.open(db) as store:
            for run in store.runs():
                fin = store.entries(run.run_id, kinds=["RunFinished"])[-1].payload
                bat = bats[run.bat_id]
                spec = bat.spec
                assert spec.hoop_hz is not None  # a simulated bat always has its hoop frequency
                model = true_bbcor(scene, spec.hoop_hz, bat.moi_kgm2, spec.length_in, fin["location_in"])
                offset = bat_offset_bbcor(scene.seed, run.bat_id, tramp.spread_bbcor)
                w_loc = fin["location_in"]
                measured = fin["mean"]
                extra = offset + bat.alteration_bbcor
                q = (bat.spec.length_in - w_loc) * INCH - scene.rig.pivot_from_knob_m
                q_s = bat.spec.length_in * INCH - tramp.sweet_spot_from_tip_m - scene.rig.pivot_from_knob_m
                w = math.exp(-0.5 * ((q - q_s) / tramp.width_m) ** 2)
                noise.append(measured - model - w * extra)
                if not bat.altered:
                    total.append(measured - model)
    print(f"{n} bats in {wall:.1f} s: {wall / n:.2f} s per certification (in-process, lab scene)")
    print(
        f"certified BBCOR - true model (with the bat's own offset): mean {statistics.fmean(noise):+.5f},"
        f" sd {statistics.stdev(noise):.5f}, max |.| {max(map(abs, noise)):.5f}"
    )
    print(
        f"legal bats, certified - true model (offset left in): mean {statistics.fmean(total):+.5f},"
        f" sd {statistics.stdev(total):.5f}  (scene spread {tramp.spread_bbcor})"
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--altered", type=int, default=0)
    a = parser.parse_args()
    run(a.n, a.seed, a.altered)
