"""Hit-by-hit decomposition of certified minus true BBCOR in the `lab` scene (docs/ball.md).

For each bat of a simulated population certified with the lot's ball terms (as
bench_ball_truth.py does), each valid hit is compared with the simulated truth for that very hit:

- chain: the hit's measured BBCOR minus the scene's collision for its ball (lot offset, wear, the
  air read at the shot), its measured speed at the bat and its location (the measurement chain);
- correction error: the verdict's correction of the hit minus the true effect of its wear and air
  at 60.8 m/s (the ball terms and the model ratio g);
- speed: the nominal ball's BBCOR at the hit's speed minus at 60.8 m/s (the aim).

Prints each bat's mean of each, then their means and SDs over the bats: a part common to every bat
(a small SD beside a non-zero mean) is a bias; one that scatters from bat to bat averages out.

    python benchmarks/bench_ball_decomposition.py [--bats 20] [--seed 42]
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks.bench_ball_truth

from benchmarks.bench_ball_truth import SCENE, certified_population, lot_terms
from rig.core.units import INCH
from rig.measure.metrics import compute_metrics
from rig.physics import CollisionParams
from rig.protocols.ball_terms import BallTerms, hit_balls
from rig.protocols.state import RunState
from rig.session import scene_with_bat
from rig.simulators.scene import Scene
from rig.simulators.truth import BBCOR_SPEED_M_S, collision_of

Parts = tuple[float, float, float]  # a bat's mean chain error, correction error, speed effect


def decompose(n: int, seed: int) -> list[Parts]:
    """Each certified bat's parts (a bat whose run ends without a verdict is said and skipped)."""
    terms = lot_terms()
    scene = Scene.load(SCENE)
    rows = []
    for spec, done, state in certified_population(n, seed, terms, "bench-decomp-"):
        if state.verdict is None or state.verdict.ball is None:
            print(f"  {spec.id}: no verdict ({done.reason})")
            continue
        parts = bat_parts(scene_with_bat(scene, spec), state, BallTerms.model_validate(terms))
        rows.append(parts)
        print(f"  {spec.id}: chain {parts[0]:+.5f}  correction {parts[1]:+.5f}  speed {parts[2]:+.5f}")
    return rows


def bat_parts(world: Scene, state: RunState, terms: BallTerms) -> Parts:
    """One certified bat's parts, each the mean over its valid hits."""
    hits = state.valid_shots("valid", state.best_location_in)
    balls = hit_balls(hits, state.environment, terms)
    collision, sim_bat = collision_of(world), world.bat
    q = sim_bat.length_m - world.rig.pivot_from_knob_m - float(state.best_location_in or 0.0) * INCH
    air = next(e for e in world.effects if e.kind == "environment")
    wear = next(e for e in world.effects if e.kind == "ball_wear")

    def bbcor(ball: CollisionParams, speed: float) -> float:
        e_a, _ = collision.collide(ball, speed, q)
        m = compute_metrics(speed, e_a * speed, q, sim_bat.moi_kgm2, ball.m1, sim_bat.length_m)
        return float(m.bbcor)

    chain, correction, speed = [], [], []
    assert state.verdict is not None and state.verdict.ball is not None, "a verdict with ball terms"
    corrections = state.verdict.ball["corrections"]
    for hit, ball, corr in zip(hits, balls, corrections, strict=True):
        draw = random.Random(f"{world.seed}/{sim_bat.id}/ball/{ball.ball}")  # the world's own draw
        own = max(0.5, 1.0 + draw.gauss(0.0, world.lot.c1_spread_rel))
        at_air = 1.0 + air.damping_per_c * (ball.temp_c - 21.0)
        at_air += air.damping_per_pct_rh * (ball.rh_pct - 50.0)
        worn = 1.0 + wear.damping_per_hit * ball.hits
        as_fired = world.ball.model_copy(update={"c1": world.ball.c1 * own * at_air * worn})
        new = world.ball.model_copy(update={"c1": world.ball.c1 * own})
        assert hit.outcome is not None, "a valid hit is evaluated"
        v_in = float(hit.outcome.inbound_at_impact_m_s or math.nan)
        chain.append(float(hit.outcome.metric or math.nan) - bbcor(as_fired, v_in))
        correction.append(float(corr) - (bbcor(new, BBCOR_SPEED_M_S) - bbcor(as_fired, BBCOR_SPEED_M_S)))
        speed.append(bbcor(world.ball, v_in) - bbcor(world.ball, BBCOR_SPEED_M_S))
    return statistics.mean(chain), statistics.mean(correction), statistics.mean(speed)


def main() -> None:
    """Print each bat's parts and their means and SDs over the bats."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bats", type=int, default=20)
    ap.add_argument("--seed", type=int, default=42)
    args = ap.parse_args()
    rows = decompose(args.bats, args.seed)
    for i, name in enumerate(("chain", "correction error", "speed")):
        values = [r[i] for r in rows]
        mean, sd = statistics.mean(values), statistics.stdev(values)
        print(f"{name}: mean {mean:+.6f} (SE {sd / len(values) ** 0.5:.6f}), SD over bats {sd:.6f}")


if __name__ == "__main__":
    main()
