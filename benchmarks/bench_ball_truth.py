"""Benchmark (issue 20's acceptance): certified BBCOR against the simulated truth in the `lab` scene.

N bats of a simulated population (default 40) are certified through the real drivers on the `lab`
scene, each on its own simulated rig, with the ball terms of a qualified lot: the lot's wear per
hit, ball-to-ball spread and sensitivity to the air measured by `ball-cor` tests on the same
simulated lab at four hours of its daily swing of air (rig.protocols.ball_air). Each certified mean is
compared with the simulated truth as the standard means it (rig.simulators.truth: the scanned location
of maximum, 60.8 m/s, a new ball of the lot's nominal condition, the bat's true MOI), computed from
the scene without the measurement chain. Prints the mean error, its standard error, how many
bats have |error| <= U and the SD of error / u (1 if the stated u is right, below 1 if cautious);
with --no-ball, the same bats without the lot's terms, for comparison.

    python benchmarks/bench_ball_truth.py [--bats 40] [--seed 7 | --seeds K] [--no-ball]
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rig.balls import run_ball_test
from rig.certification import Outcome, certify, history
from rig.core.ball import BallLot, Conditioning
from rig.core.bat import BatSpec
from rig.protocols.ball_procedure import BallProcedure
from rig.protocols.ball_terms import terms_from_lot
from rig.protocols.procedure import Procedure
from rig.protocols.state import RunState, fold
from rig.session import air_starting_at, scene_with_bat, sim_config
from rig.simulators.scene import Scene
from rig.simulators.truth import true_metric
from rig.store import Store
from studies.population.simulated import simulated_population

SCENE = "lab"


HOURS = 4  # ball-cor tests of the lot at this many points of the lab's daily swing of air


def lot_terms(lot_id: str = "SIM-LOT", hours: int = HOURS) -> dict[str, Any]:
    """The lot's ball terms, measured by ball-cor tests on the same simulated lab (its own store):
    one test at each of `hours` evenly spaced points of the lab's swing of air, so the lot's
    sensitivity to the air is measured too (rig.protocols.ball_air)."""
    procedure = BallProcedure.load("ball-cor")
    lot = BallLot(
        id=lot_id,
        maker="simulated",
        model="lab ball",
        conditioning=Conditioning(temperature_c=21.0, humidity_pct=50.0),
    )
    target = (procedure.target.kind, procedure.target.diameter_m)
    period = next(float(e.period_s) for e in Scene.load(SCENE).effects if e.kind == "environment")
    with tempfile.TemporaryDirectory() as folder, Store.open(Path(folder) / "lot.db") as store:
        store.register_lot(lot)
        for hour in range(hours):
            at = air_starting_at(period * hour / hours)
            run_ball_test(store, procedure, lot, sim_config(SCENE, target=target, effects=at))
        lot_now, results = store.ball_lot(lot_id)
        return terms_from_lot(lot_now, results).model_dump(mode="json")


def certified_population(
    n: int, seed: int, terms: dict[str, Any] | None, prefix: str
) -> Iterator[tuple[BatSpec, Outcome, RunState]]:
    """Each bat of the simulated population certified on the lab scene (with the lot's ball terms
    if given): its spec, its run's outcome and the run's folded state."""
    folder = Path(tempfile.mkdtemp(prefix=prefix))
    for bat in simulated_population(n, seed, 0, 0.0):
        path = folder / f"{bat.spec.id}.toml"
        path.write_text(bat.toml(SCENE, seed))
        spec = BatSpec.load(path)
        with Store.open(folder / "runs.db") as store:
            done = certify(store, Procedure.load("bbcor"), spec, sim_config(SCENE, bat=spec), ball=terms)
            state = fold(history(store, done.run_id))
        yield spec, done, state


def run(n: int, seed: int, with_ball: bool) -> list[tuple[str, float, float, float, float]]:
    """(bat id, certified mean, truth, U, u) for each bat."""
    scene = Scene.load(SCENE)
    terms = lot_terms() if with_ball else None
    out = []
    for spec, done, state in certified_population(n, seed, terms, "bench-ball-"):
        verdict = state.verdict
        if (
            verdict is None or verdict.mean is None or verdict.U is None or verdict.u is None
        ):  # the run stopped (e.g. its re-shoot budget): no value, not covered
            print(f"  {spec.id}: no verdict ({done.status}: {done.reason})")
            out.append((spec.id, math.nan, math.nan, math.nan, math.nan))
            continue
        scanned = tuple(sorted({s.location_in for s in state.shots if s.purpose == "scan"}))
        truth = true_metric(scene_with_bat(scene, spec), scanned)
        out.append((spec.id, float(verdict.mean), truth.value, float(verdict.U), float(verdict.u)))
    return out


def main() -> None:
    """Print the acceptance figures (with --seeds K, the mean error of each of K populations)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bats", type=int, default=40)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--seeds", type=int, default=0, help="K populations (seeds 1..K): the mean over them")
    ap.add_argument("--no-ball", action="store_true", help="certify without the lot's ball terms")
    args = ap.parse_args()
    if args.seeds:
        over_seeds(args.bats, args.seeds, not args.no_ball)
    else:
        one_population(args.bats, args.seed, not args.no_ball)


def one_population(bats: int, seed: int, with_ball: bool) -> None:
    """Each bat's error, the mean error, the coverage and the SD of error / u."""
    t0 = time.perf_counter()
    every = run(bats, seed, with_ball)
    rows = [r for r in every if not math.isnan(r[1])]
    errors = [m - t for _, m, t, _, _ in rows]
    covered = sum(1 for (_, m, t, big_u, _) in rows if abs(m - t) <= big_u)
    mean = statistics.mean(errors)
    se = statistics.stdev(errors) / math.sqrt(len(errors)) if len(errors) > 1 else float("nan")
    print(f"scene {SCENE}, {len(rows)} bats, ball terms {'from the lot' if with_ball else 'off'}")
    for bat, m, t, big_u, _ in rows:
        print(f"  {bat}: certified {m:.5f}  truth {t:.5f}  error {m - t:+.5f}  U {big_u:.5f}")
    print(f"mean error {mean:+.5f} (standard error {se:.5f}; target within +-0.0005)")
    share = 100 * covered / len(every)
    print(f"|error| <= U for {covered} of {len(every)} bats ({share:.0f} %; target >= 95 %)")
    if len(rows) < len(every):
        print(f"{len(every) - len(rows)} bats without a verdict (counted as not covered)")
    z = [(m - t) / u for _, m, t, _, u in rows]
    print(f"SD of error / u {statistics.pstdev(z):.2f} (1: the stated u is right; below 1: cautious)")
    print(f"median U {statistics.median(r[3] for r in rows):.5f}; {time.perf_counter() - t0:.1f} s")


def over_seeds(bats: int, seeds: int, with_ball: bool) -> None:
    """The mean error of each population and their mean: a bias common to every bat shows here."""
    means, covered, total = [], 0, 0
    for seed in range(1, seeds + 1):
        every = run(bats, seed, with_ball)
        rows = [r for r in every if not math.isnan(r[1])]
        means.append(statistics.mean(m - t for _, m, t, _, _ in rows))
        covered += sum(1 for (_, m, t, big_u, _) in rows if abs(m - t) <= big_u)
        total += len(every)
        print(f"  seed {seed}: mean error {means[-1]:+.5f}", flush=True)
    se = statistics.stdev(means) / math.sqrt(len(means)) if len(means) > 1 else float("nan")
    print(f"{seeds} populations of {bats} bats: mean error {statistics.mean(means):+.6f} (SE {se:.6f})")
    print(f"largest |population mean| {max(map(abs, means)):.5f} (target within +-0.0005 each)")
    print(f"|error| <= U for {covered} of {total} bats ({100 * covered / total:.1f} %)")


if __name__ == "__main__":
    main()
