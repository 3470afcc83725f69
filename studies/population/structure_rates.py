"""How often the residual-structure check refuses: flat-topped spreads (one construction whose
contact stiffness varies widely: no second group) against two groups 5 SD apart, over seeds.

    python -m studies.population.structure_rates [--trials 40]

Prints, for each kind of residuals and 20, 40, 200 and 1,000 bats, how many of `trials` seeds
`rig.population.structure.check_structure` refuses (docs/crosscheck.md quotes them).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from rig.population.structure import ModelFamilyRefused, check_structure

Residuals = Callable[[np.random.Generator, int], np.ndarray]
KINDS: dict[str, Residuals] = {
    "flat (uniform +-0.02, noise 0.002)": lambda g, n: g.uniform(-0.02, 0.02, n) + g.normal(0, 0.002, n),
    "normal (SD 0.005)": lambda g, n: g.normal(0, 0.005, n),
    "two groups, 30 % at +5 SD": lambda g, n: np.where(g.random(n) < 0.3, 0.02, 0.0) + g.normal(0, 0.004, n),
    "two groups, 15 % at +5 SD": lambda g, n: np.where(g.random(n) < 0.15, 0.02, 0.0) + g.normal(0, 0.004, n),
    "two groups, 50 % at +4 SD": lambda g, n: np.where(g.random(n) < 0.5, 0.016, 0.0) + g.normal(0, 0.004, n),
    "two groups, 15 % at +4 SD": lambda g, n: (
        np.where(g.random(n) < 0.15, 0.016, 0.0) + g.normal(0, 0.004, n)
    ),
    "lognormal (skewed, one group)": lambda g, n: 0.005 * g.lognormal(0.0, 1.0, n),
}
SIZES = (20, 40, 200, 1000)


def refused(kind: Residuals, n: int, trials: int) -> int:
    """Seeds 0..trials-1 of `kind` at n bats (hoops drawn apart) that the check refuses."""
    count = 0
    for seed in range(trials):
        rng = np.random.default_rng(seed)
        hoops = rng.uniform(1400.0, 3000.0, n)
        try:
            check_structure(hoops.tolist(), kind(rng, n).tolist(), "study")
        except ModelFamilyRefused:
            count += 1
    return count


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--trials", type=int, default=40)
    args = parser.parse_args(argv)
    print(f"refused of {args.trials} seeds at " + ", ".join(f"{n}" for n in SIZES) + " bats")
    for name, kind in KINDS.items():
        print(f"{name:<36} " + "  ".join(f"{refused(kind, n, args.trials):3d}" for n in SIZES))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
