"""Benchmark: `rig model calibrate` on 40, 400 and 4,000 bats, `rig model crosscheck` on 40: ratios to B.

B is the wall time of a fresh `python -c "import numpy, scipy.integrate"`, measured just before
each command in every round (the machine's load moves); the ratio printed is the median over
--repeats rounds. Each command runs as a lab runs it: a fresh process,
`python -m rig.cli model calibrate --data POP.csv --output CAL.json`. The populations are the
one-mode model at the simulated lab's truth (m2 = 0.24 kg, c2 = 300 N s/m, k1 x 0.9, each bat at
6-7 in) plus 0.005 BBCOR of scatter, the bats drawn as in the tests (hoop 1400-3000 Hz, 31-34 in).
Targets (issue 26): 400 bats <= 10 B, 4,000 bats <= 60 B, crosscheck of 40 bats <= 1.5 B.

    python benchmarks/bench_calibrate.py [--repeats 2] [--sizes 40,400,4000]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rig.core.bat import Barrel
from rig.population import PopulationBat, write_population_csv
from rig.population.calibrate import fit_bats, predict

TARGETS = {400: 10.0, 4000: 60.0}
CROSSCHECK_TARGET = 1.5
TRUTH = {"m2": 0.24, "c2": 300.0, "k1_scale": 0.9}


def population(n: int, seed: int) -> list[PopulationBat]:
    """n bats: the model at TRUTH plus 0.005 BBCOR of scatter (one batch of solves)."""
    rng = np.random.default_rng(seed)
    bats = []
    for i in range(n):
        length = float(rng.choice([31.0, 32.0, 33.0, 34.0]))
        bats.append(
            PopulationBat(
                bat_id=f"P{seed}-{i:04d}",
                barrel=Barrel.COMPOSITE,
                hoop_hz=round(float(rng.uniform(1400.0, 3000.0)), 1),
                length_in=length,
                moi_kgm2=round(0.19 + 0.012 * (length - 33.0) + float(rng.normal(0.0, 0.008)), 5),
                location_in=round(float(rng.uniform(6.0, 7.0)), 2),
                bbcor=0.5,  # replaced below
                u_bbcor=0.003,
                source="benchmark: the model at the lab's truth + 0.005 scatter",
            )
        )
    truth = predict(fit_bats(bats, "bbcor"), TRUTH)
    noise = rng.normal(0.0, 0.005, n)
    return [
        b.model_copy(update={"bbcor": round(float(v + e), 5)})
        for b, v, e in zip(bats, truth, noise, strict=True)
    ]


def wall(argv: list[str]) -> float:
    """Seconds a fresh process takes; RuntimeError naming the command if it fails."""
    t0 = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, timeout=3600)
    took = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(argv[3:5])} exit {done.returncode}: {done.stderr.strip()[-300:]}")
    return took


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=2, help="timed rounds (the median ratio counts)")
    p.add_argument("--sizes", default="40,400,4000", help="population sizes to calibrate")
    a = p.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    rig = [sys.executable, "-m", "rig.cli", "model"]
    with tempfile.TemporaryDirectory(prefix="rig-bench-calibrate-") as tmp:
        folder = Path(tmp)
        data = {
            n: write_population_csv(population(n, seed=n), folder / f"pop{n}.csv", ("benchmark",))
            for n in sizes
        }
        fresh = write_population_csv(population(40, seed=7), folder / "fresh40.csv", ("benchmark",))
        base = [sys.executable, "-c", "import numpy, scipy.integrate"]
        details: dict[int, str] = {}
        runs = {
            f"calibrate {n}": [
                *rig,
                "calibrate",
                "--data",
                str(data[n]),
                "--output",
                str(folder / f"cal{n}.json"),
            ]
            for n in sizes
        }
        if 40 in sizes:
            runs["crosscheck 40"] = [
                *rig,
                "crosscheck",
                "--data",
                str(fresh),
                "--calibration",
                str(folder / "cal40.json"),
            ]
        seconds: dict[str, list[float]] = {name: [] for name in runs}
        ratios: dict[str, list[float]] = {name: [] for name in runs}
        for round_ in range(a.repeats + 1):  # round 0 warms up (bytecode, numba's cache)
            for name, argv in runs.items():
                b, t = wall(base), wall(argv)  # B beside each command: the machine's load moves
                print(f"  round {round_}: B {b:.2f} s, {name} {t:.2f} s", file=sys.stderr, flush=True)
                if round_:
                    seconds[name].append(t)
                    ratios[name].append(t / b)
        for n in sizes:
            rec = json.loads((folder / f"cal{n}.json").read_text())
            details[n] = (
                f"chosen {rec['variant']}, LOO RMSE {rec['loo_rmse']:.4f}, scatter {rec['scatter']:.4f}"
            )
    print(
        f"each command's time over B (python -c 'import numpy, scipy.integrate') measured just before it,"
        f" median of {a.repeats} rounds (the best time in brackets)"
    )
    ok = True
    for name in runs:
        n = int(name.split()[1])
        target = CROSSCHECK_TARGET if name.startswith("crosscheck") else TARGETS.get(n)
        ratio = float(np.median(ratios[name]))
        met = target is None or ratio <= target
        ok &= met
        verdict = "" if target is None else f"  (target <= {target:g} B: {'MET' if met else 'NOT MET'})"
        tail = f"; {details[n]}" if name.startswith("calibrate") else ""
        print(f"rig model {name:>15s} bats: {ratio:6.1f} B ({min(seconds[name]):6.2f} s){verdict}{tail}")
    print(f"targets {'MET' if ok else 'NOT MET'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
