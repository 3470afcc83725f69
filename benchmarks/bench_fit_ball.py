"""Benchmark: is the ball fit's stated sigma honest? Coverage of a and b over N seeds, and time per fit.

CCOR data come from the tests' own rigid-wall solver (tests/ball/reference_ccor.py: scipy solve_ivp
with its own contact-end event, no rig.physics): a = 0.70, b = 0.55 (k1, c1, m1 the paper's),
five speeds 25-60 m/s, B balls per speed, Gaussian ball-to-ball scatter. Each seed is fitted by
`rig.ball.fit.fit_ball` (every variant, leave-one-ball-out, the choice). Prints, per parameter,
the fraction of seeds whose estimate lies within 1 and 2 stated sigma of the truth (nominal
about 68 % and 95 %, Student-t with n - 2 degrees of freedom), the mean stated sigma against the
spread of the estimates, how often each variant was chosen, and the time per fit.

    python benchmarks/bench_fit_ball.py [--seeds 40] [--balls 4] [--noise 0.0005] [--weighted]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.ball.fit import BallFitRefused, fit_ball  # noqa: E402
from tests.ball.synthetic import NOISE, TRUE, ccor_points  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--balls", type=int, default=4, help="balls per speed (one shot each)")
    parser.add_argument("--noise", type=float, default=NOISE, help="ball-to-ball CCOR scatter (1 sigma)")
    parser.add_argument("--weighted", action="store_true", help="give each point u_ccor = noise")
    args = parser.parse_args()
    ccor_points(seed=0, balls=1)  # the reference solves of the truth, cached, outside the timing
    fit_ball(ccor_points(seed=0, balls=args.balls))  # the compiled kernel loads outside the timing
    within = {n: [0, 0] for n in ("a", "b")}
    values: dict[str, list[float]] = {"a": [], "b": []}
    sigmas: dict[str, list[float]] = {"a": [], "b": []}
    chosen: Counter[str] = Counter()
    times = []
    for seed in range(1000, 1000 + args.seeds):
        points = ccor_points(seed, noise=args.noise, balls=args.balls, with_u=args.weighted)
        t0 = time.perf_counter()
        try:
            result = fit_ball(points)
        except BallFitRefused as exc:
            chosen[f"refused ({str(exc)[:60]}...)"] += 1
            continue
        finally:
            times.append(time.perf_counter() - t0)
        chosen[result.chosen] += 1
        fit = result.reports["a+b"].fit
        for n, s in fit.errors().items():
            err = abs(fit.values[n] - TRUE[n])
            within[n][0] += err <= s
            within[n][1] += err <= 2 * s
            values[n].append(fit.values[n])
            sigmas[n].append(s)
    n_points = 5 * args.balls
    fitted = len(values["a"])
    print(
        f"ball fit: {args.seeds} seeds, {n_points} points (5 speeds 25-60 m/s x {args.balls} balls),"
        f" noise {args.noise:g}, {'weighted by u_ccor' if args.weighted else 'unweighted'}, {fitted} fitted;"
        f" truth a = {TRUE['a']}, b = {TRUE['b']}"
    )
    for n in ("a", "b"):
        if fitted < 2:
            break
        one, two = (100.0 * k / fitted for k in within[n])
        print(
            f"  {n}: within 1 sigma {one:5.1f} %, within 2 sigma {two:5.1f} %;"
            f" mean stated sigma {statistics.fmean(sigmas[n]):.4f},"
            f" spread of estimates {statistics.stdev(values[n]):.4f},"
            f" mean bias {statistics.fmean(values[n]) - TRUE[n]:+.4f}"
        )
    print(f"  chosen: {dict(chosen)}")
    print(
        f"  time per fit (3 variants, leave-one-ball-out): median {1e3 * statistics.median(times):.0f} ms,"
        f" max {1e3 * max(times):.0f} ms"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
