"""A simulated bat population to certify on the simulated rig: bat files and their hidden truth.

`rig-study population --certify N` certifies such bats one by one on a simulated lab. Each bat is
drawn from the population's seed and its own index only, so the same (seed, index) is always the
same bat: hoop frequency 1400-3000 Hz spread evenly (a golden-ratio sequence from a seeded start),
length 31-34 in with drop -3, MOI about the pivot 0.19 + 0.012 (length - 33 in) kg m^2 plus a 0.008
kg m^2 spread (as a realistic BBCOR bat), balance point two thirds of the length. The bat file
holds what a lab would know (id, length, weight, barrel, hoop, balance point); the true MOI (the
rig measures it on the pivot) and an alteration are the simulated world's. Altered bats' ids start
with ALT- and their file says so in a comment; the hoop frequency is the unaltered bat's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.core.bat import Barrel, BatSpec

HOOP_RANGE_HZ = (1400.0, 3000.0)
LENGTHS_IN = (31.0, 32.0, 33.0, 34.0)
DROP_OZ = 3.0
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
ALTERED_PREFIX = "ALT-"


@dataclass(frozen=True)
class SimulatedBat:
    """One bat of a simulated population: its file's contents and what only the simulation knows."""

    index: int
    spec: BatSpec
    moi_kgm2: float  # true MOI about the pivot
    alteration_bbcor: float  # 0 for a legal bat

    @property
    def altered(self) -> bool:
        """True for a bat given an alteration."""
        return self.alteration_bbcor != 0.0

    def toml(self, scene: str, seed: int) -> str:
        """The bat file (TOML), with comments on where it comes from."""
        s = self.spec
        lines = [
            f"# Simulated bat {self.index} of population seed {seed}"
            f" (rig-study population --certify, scene {scene}).",
            "# The [simulated] table holds the simulated bat's true properties: only the simulated rig",
            "# reads it; the controller measures the MOI on the pivot.",
        ]
        if self.altered:
            lines.append(
                f"# ALTERED: +{self.alteration_bbcor:g} BBCOR beyond the legal bat; hoop_hz is the"
                " unaltered bat's."
            )
        lines += [
            "[bat]",
            f'id = "{s.id}"',
            f"length_in = {s.length_in!r}",
            f"weight_oz = {s.weight_oz!r}",
            f'barrel = "{s.barrel.value}"',
            f"hoop_hz = {s.hoop_hz!r}",
            f"balance_point_in = {s.balance_point_in!r}",
            "",
            "[simulated]",
            f"moi_kgm2 = {self.moi_kgm2!r}",
        ]
        if self.altered:
            lines.append(f"alteration_bbcor = {self.alteration_bbcor!r}")
        return "\n".join(lines) + "\n"


def altered_indices(n: int, altered: int) -> frozenset[int]:
    """Which of n bats are altered: `altered` of them spread evenly over the list."""
    return frozenset(int((j + 0.5) * n / altered) for j in range(altered)) if altered else frozenset()


def simulated_bat(seed: int, index: int, alteration_bbcor: float = 0.0) -> SimulatedBat:
    """Bat `index` (1-based) of the population `seed`; an alteration makes it an ALT- bat."""
    start = float(np.random.default_rng([seed, 0]).random())
    rng = np.random.default_rng([seed, index])
    lo, hi = HOOP_RANGE_HZ
    hoop = lo + (hi - lo) * ((start + index * GOLDEN) % 1.0)
    length = float(rng.choice(LENGTHS_IN))
    moi = 0.19 + 0.012 * (length - 33.0) + float(rng.normal(0.0, 0.008))
    balance = round(length * 2.0 / 3.0 + float(rng.normal(0.0, 0.25)), 2)
    prefix = ALTERED_PREFIX if alteration_bbcor else "SIM-"
    spec = BatSpec(
        id=f"{prefix}S{seed}-{index:03d}",
        length_in=length,
        weight_oz=length - DROP_OZ,
        barrel=Barrel.ALUMINIUM,
        hoop_hz=round(hoop, 1),
        balance_point_in=balance,
    )
    return SimulatedBat(index, spec, round(moi, 5), alteration_bbcor)


def simulated_population(
    n: int, seed: int = 0, altered: int = 0, alteration_bbcor: float = 0.025
) -> list[SimulatedBat]:
    """n bats, `altered` of them (spread over the list) with `alteration_bbcor` added."""
    if not 0 <= altered <= n:
        raise ValueError(f"altered bats {altered} must be between 0 and the {n} bats")
    chosen = altered_indices(n, altered)
    return [simulated_bat(seed, i + 1, alteration_bbcor if i in chosen else 0.0) for i in range(n)]
