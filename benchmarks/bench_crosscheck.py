"""Benchmark: the cross-check's power on simulated populations (issue 10's goal).

For each of R simulated populations (the `lab` scene: its own "true" barrel, not the paper's, and a
per-bat spread): calibrate on 40 legal bats, then cross-check 40 fresh legal bats and the same 40
bats altered by +0.01, +0.02, +0.025 and +0.03 BBCOR. Prints the prediction error (RMSE of the
calibrated prediction against the fresh bats' measured values), the false-flag rate of legal bats
and the detection rate of each alteration, pooled over the populations, with a 95 % Wilson
interval for each rate, and the time a calibration costs.

Two tiers, both in one run:
1. Certified (`--certified N`, default 40): N legal bats and 20 more (10 of them altered by
   +0.025) certified on the simulated rig through the real drivers into stores (`rig-study
   population --certify`), the calibration made from the store, and the 20 cross-checked: the
   pipeline a lab runs. It also measures what the Monte Carlo needs: the certified means' scatter about the
   simulated rig's own truth and the uncertainty the runs record.
2. Monte Carlo (`--populations R`): each bat's measured value is the simulated rig's own collision
   at the location its scan would choose (the grid maximum) plus Gaussian noise of the size tier 1
   measured (studies/population/lab.py); u_bbcor is the median u the runs recorded.

Goal (issue 10): altered +0.025 flagged >= 3 in 4, legal flagged <= 1 in 10, RMSE <= 0.007.

    python benchmarks/bench_crosscheck.py [--populations 10] [--certified 40] [--figure DIR]
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rig.population.calfile import CalibrationFile, calibration_record
from rig.population.calibrate import CalibrationRefused, calibrate
from rig.population.crosscheck import crosscheck_bats
from rig.population.store_source import bats_from_store
from rig.simulators.scene import Scene
from rig.store import Store
from studies.cli import main as study_main
from studies.population.lab import Variation, best_scan_location, measured_population, true_metric
from studies.population.simulated import SimulatedBat, simulated_population

ALTERATIONS = (0.01, 0.02, 0.025, 0.03)
GOAL = {"detect_0.025": 0.75, "false_flag": 0.10, "rmse": 0.007}


@dataclass
class Tally:
    """Pooled counts over the populations."""

    n_legal: int = 0
    false_flags: int = 0
    detected: dict[float, int] = field(default_factory=lambda: dict.fromkeys(ALTERATIONS, 0))
    n_altered: int = 0
    sq_err: list[float] = field(default_factory=list)
    loo_rmse: list[float] = field(default_factory=list)
    variants: list[str] = field(default_factory=list)
    fit_s: list[float] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)  # populations the calibration refused, and why

    @property
    def rmse(self) -> float:
        """Root mean square prediction error over every fresh legal bat."""
        return math.sqrt(float(np.mean(self.sq_err)))


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k / n."""
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def certify_into(db: Path, n: int, seed: int, altered: int) -> dict[str, SimulatedBat]:
    """`rig-study population --certify` n bats (of them `altered` +0.025) into db; the bats by id."""
    flags = ["--certify", str(n), "--db", str(db), "--seed", str(seed), "--altered", str(altered)]
    code = study_main(["population", *flags, "--alteration", "0.025"])
    if code != 0:
        raise SystemExit(f"rig-study population --certify failed with exit {code}")
    return {b.spec.id: b for b in simulated_population(n, seed, altered, 0.025)}


def certified_tier(scene: Scene, n: int, seed: int) -> tuple[float, float]:
    """Tier 1: certify, calibrate from the store, cross-check fresh and altered bats.

    Returns (sd of certified - truth, median recorded u) for the Monte Carlo.
    """
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        train_bats = certify_into(Path(tmp) / "train.db", n, seed, 0)
        test_bats = certify_into(Path(tmp) / "test.db", 20, seed + 500, 10)
        wall = time.perf_counter() - t0
        with Store.open(Path(tmp) / "train.db") as store:
            train, _ = bats_from_store(store)
        with Store.open(Path(tmp) / "test.db") as store:
            test, _ = bats_from_store(store)
    print(
        f"tier 1: {n + 20} bats certified on the simulated lab in {wall:.0f} s ({wall / (n + 20):.2f} s each)"
    )
    every = {**train_bats, **test_bats}
    err = [
        b.bbcor - true_metric(scene, every[b.bat_id], b.location_in or 0.0) for b in train + test if b.bbcor
    ]
    us = [b.u_bbcor for b in train + test if b.u_bbcor is not None]
    locs = [b.location_in for b in train + test if b.location_in is not None]
    print(
        f"  certified - simulated truth: mean {statistics.fmean(err):+.5f}, sd {statistics.stdev(err):.5f};"
        f" recorded u (k = 1): median {statistics.median(us):.5f}; chosen locations"
        f" {min(locs):g}-{max(locs):g} in"
    )
    cal = calibrate(train, "bbcor")
    record = CalibrationFile.model_validate(calibration_record(cal, b"certified", "tier 1"))
    checks = crosscheck_bats(record, test)
    legal = [c for c in checks if not every[c.bat_id].altered]
    alt = [c for c in checks if every[c.bat_id].altered]
    print(
        f"  calibrated on {len(train)} certified bats: {record.variant}, scatter {record.scatter:.4f},"
        f" LOO RMSE {record.loo_rmse:.4f}"
    )
    print(
        f"  fresh certified bats: legal flagged {sum(bool(c.flagged) for c in legal)} / {len(legal)},"
        f" altered +0.025 flagged {sum(bool(c.flagged) for c in alt)} / {len(alt)};"
        f" z legal {' '.join(f'{c.z:+.1f}' for c in legal if c.z is not None)};"
        f" z altered {' '.join(f'{c.z:+.1f}' for c in alt if c.z is not None)}"
    )
    return statistics.stdev(err), statistics.median(us)


def one_population(
    scene: Scene, seed: int, n: int, noise: float, u: float, tally: Tally, vary: Variation | None = None
) -> None:
    """Calibrate on n legal bats, cross-check n fresh legal bats and their altered twins."""
    rng = np.random.default_rng([seed, 7])
    bats = simulated_population(n, seed)
    train = measured_population(scene, bats, best_scan_location, noise, rng, u=u, vary=vary)
    t0 = time.perf_counter()
    try:
        cal = calibrate(train, "bbcor")
    except CalibrationRefused as exc:  # counted and shown: a lab would be told the same
        tally.refused.append(f"population {seed}: {exc}")
        return
    tally.fit_s.append(time.perf_counter() - t0)
    record = CalibrationFile.model_validate(calibration_record(cal, b"simulated", f"population {seed}"))
    tally.variants.append(record.variant)
    tally.loo_rmse.append(record.loo_rmse)
    fresh_bats = simulated_population(n, seed + 100_000)
    fresh = measured_population(scene, fresh_bats, best_scan_location, noise, rng, u=u, vary=vary)
    checks = crosscheck_bats(record, fresh)
    tally.n_legal += len(checks)
    tally.false_flags += sum(bool(c.flagged) for c in checks)
    tally.sq_err += [(c.measured - c.predicted) ** 2 for c in checks if c.measured is not None]
    tally.n_altered += len(checks)
    for delta in ALTERATIONS:
        # the same bats, altered: the same noise draws, so the levels are compared pairwise
        shifted = [b.model_copy(update={"bbcor": b.bbcor + delta}) for b in fresh if b.bbcor is not None]
        tally.detected[delta] += sum(bool(c.flagged) for c in crosscheck_bats(record, shifted))


def report(tally: Tally, populations: int, n: int, noise: float, u: float, spread: float) -> dict[str, float]:
    """Print the table; return the headline figures."""
    print(
        f"tier 2: {populations} simulated populations (lab scene, bat-to-bat spread {spread:g} BBCOR,"
        f" measurement noise {noise:.5f}, recorded u {u:.5f}): calibrated on {n} legal bats each,"
        f" cross-checked on {n} fresh bats each, 95 % prediction intervals"
        + (f"; {len(tally.refused)} refused by the calibration" if tally.refused else "")
    )
    print(
        f"calibration: {np.mean(tally.fit_s):.1f} s each (median {np.median(tally.fit_s):.1f} s);"
        f" variants chosen: {', '.join(sorted(set(tally.variants)))}"
        f" ({', '.join(f'{v} x{tally.variants.count(v)}' for v in sorted(set(tally.variants)))})"
    )
    for why in tally.refused:
        print(f"calibration refused, population left out: {why}")
    print(f"leave-one-out RMSE (in the calibration set): mean {np.mean(tally.loo_rmse):.4f}")
    print(f"prediction RMSE on fresh legal bats:         {tally.rmse:.4f}   (goal <= {GOAL['rmse']})")
    lo, hi = wilson(tally.false_flags, tally.n_legal)
    rate = tally.false_flags / tally.n_legal
    print(
        f"legal bats flagged:     {tally.false_flags:4d} / {tally.n_legal}  = {rate:.3f}"
        f"  [{lo:.3f}, {hi:.3f}]   (goal <= {GOAL['false_flag']})"
    )
    out = {"rmse": tally.rmse, "false_flag": rate}
    for delta in ALTERATIONS:
        k = tally.detected[delta]
        lo, hi = wilson(k, tally.n_altered)
        goal = f"   (goal >= {GOAL['detect_0.025']})" if delta == 0.025 else ""
        print(
            f"altered +{delta:<5g} flagged: {k:4d} / {tally.n_altered}  = {k / tally.n_altered:.3f}"
            f"  [{lo:.3f}, {hi:.3f}]{goal}"
        )
        out[f"detect_{delta:g}"] = k / tally.n_altered
    met = (
        out["detect_0.025"] >= GOAL["detect_0.025"]
        and out["false_flag"] <= GOAL["false_flag"]
        and out["rmse"] <= GOAL["rmse"]
    )
    print(f"goal {'MET' if met else 'NOT MET'}")
    return out


def figure(tally: Tally, out_dir: Path, noise: float) -> list[Path]:
    """Detection rate against alteration, with the false-flag rate at 0 (SVG and PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = [0.0, *ALTERATIONS]
    ks = [tally.false_flags, *(tally.detected[d] for d in ALTERATIONS)]
    ns = [tally.n_legal, *([tally.n_altered] * len(ALTERATIONS))]
    rates = [k / n for k, n in zip(ks, ns, strict=True)]
    cis = [wilson(k, n) for k, n in zip(ks, ns, strict=True)]
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    ax.errorbar(
        xs,
        rates,
        yerr=[
            [r - c[0] for r, c in zip(rates, cis, strict=True)],
            [c[1] - r for r, c in zip(rates, cis, strict=True)],
        ],
        marker="o",
        capsize=3,
        label="flagged (95 % Wilson interval)",
    )
    ax.axhline(0.75, color="tab:green", ls="--", lw=1, label="goal: +0.025 flagged >= 3/4")
    ax.axhline(0.10, color="tab:red", ls=":", lw=1, label="goal: legal flagged <= 1/10")
    ax.set_xlabel("alteration, BBCOR (0 = legal bats)")
    ax.set_ylabel("share of bats flagged")
    ax.set_ylim(0, 1.02)
    ax.set_title(f"Cross-check power: calibrated on 40 bats, noise {noise:g} BBCOR", fontsize=10)
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in ("svg", "png"):
        path = out_dir / f"crosscheck-power.{ext}"
        fig.savefig(path, dpi=120, metadata={"Date": None} if ext == "svg" else None)
        paths.append(path)
    plt.close(fig)
    return paths


def main() -> None:
    """Run the study and print it."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--populations", type=int, default=10)
    p.add_argument("--bats", type=int, default=40)
    p.add_argument("--certified", type=int, default=40, help="tier 1: bats certified to calibrate (0: skip)")
    p.add_argument("--noise", type=float, default=0.001, help="sd of a certified mean when tier 1 is skipped")
    p.add_argument(
        "--u", type=float, default=0.003, help="recorded u of a certified mean when tier 1 is skipped"
    )
    p.add_argument("--seed", type=int, default=1)
    p.add_argument(
        "--spread", type=float, default=None, help="bat-to-bat spread, BBCOR (default: the lab scene's)"
    )
    p.add_argument(
        "--vary-k1", type=float, default=0.0, help="each bat's contact stiffness x 1 + U(-v, v) (Monte Carlo)"
    )
    p.add_argument(
        "--vary-m2", type=float, default=0.0, help="each bat's hoop mass m2 x 1 + U(-v, v) (Monte Carlo)"
    )
    p.add_argument("--figure", type=Path, default=None, help="write crosscheck-power.svg/png here")
    a = p.parse_args()
    scene = Scene.load("lab")
    if a.spread is not None:  # the Monte Carlo's world only; tier 1 certifies on the scene as shipped
        scene = scene.with_effect("trampoline", spread_bbcor=a.spread)
    spread = next(e.spread_bbcor for e in scene.effects if e.kind == "trampoline")
    noise, u = a.noise, a.u
    if a.certified:
        noise, u = certified_tier(Scene.load("lab"), a.certified, a.seed + 900)
    tally = Tally()
    for r in range(a.populations):
        before = len(tally.refused)
        one_population(scene, a.seed + r, a.bats, noise, u, tally, Variation(a.vary_k1, a.vary_m2))
        ok = len(tally.refused) == before
        done = f"{tally.variants[-1]}, LOO RMSE {tally.loo_rmse[-1]:.4f}" if ok else "calibration refused"
        print(f"  population {r + 1}/{a.populations}: {done}", flush=True)
    if a.vary_k1 or a.vary_m2:
        print(f"each bat's barrel varies: k1 x 1 +- {a.vary_k1:g}, m2 x 1 +- {a.vary_m2:g} (uniform)")
    report(tally, a.populations, a.bats, noise, u, spread)
    if a.figure:
        for path in figure(tally, a.figure, noise):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
