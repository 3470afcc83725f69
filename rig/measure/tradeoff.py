"""What accuracy costs in lab time: u of a bat's mean result against the number of valid hits.

For n like hits, u^2(mean) = u_random^2 / n + u_systematic^2 (timing averages down, the shared
inputs - gate positions, Q, I, ball mass - do not), so the table flattens at the systematic floor.
Lab time counts the cannon cycle per shot fired and a ring check before the first shot and after
every shot (NCAA: the ring passes over the bat before and after every hit).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from rig.core.errors import ParameterError
from rig.measure.uncertainty import Budget

DEFAULT_CYCLE_S = 60.0  # fill, fire, retrieve the ball [assumed: no source gives a cycle time]
DEFAULT_RING_CHECK_S = 20.0  # pass the ring over the whole bat [assumed]


@dataclass(frozen=True)
class TradeoffRow:
    """n valid hits: standard and expanded uncertainty of the mean, shots fired, lab time."""

    hits: int
    u: float
    expanded: float
    shots: int
    lab_time_s: float

    def as_dict(self) -> dict[str, float | int]:
        """Plain values for a report table."""
        return asdict(self)


def _per_hit(per_hit: Budget, output: str) -> tuple[float, float]:
    if per_hit.n_hits != 1:
        raise ParameterError("per_hit", per_hit.n_hits, "needs the budget of a single hit")
    return per_hit.random_variance(output), per_hit.systematic_variance(output)


def mean_u(per_hit: Budget, n: int, output: str = "bbcor") -> float:
    """Standard uncertainty of the mean of n like hits."""
    if n < 1:
        raise ParameterError("n", n, "at least one hit")
    rand, sys = _per_hit(per_hit, output)
    return math.sqrt(rand / n + sys)


def lab_time_s(
    shots: int, cycle_s: float = DEFAULT_CYCLE_S, ring_check_s: float = DEFAULT_RING_CHECK_S
) -> float:
    """Time to fire `shots` shots with a ring check before the first and after each."""
    return shots * cycle_s + (shots + 1) * ring_check_s


def tradeoff_table(
    per_hit: Budget,
    output: str = "bbcor",
    max_hits: int = 20,
    cycle_s: float = DEFAULT_CYCLE_S,
    ring_check_s: float = DEFAULT_RING_CHECK_S,
    valid_fraction: float = 1.0,
) -> list[TradeoffRow]:
    """Rows for n = 1..max_hits valid hits; `valid_fraction` of shots count (the rest are re-shot)."""
    if not 0.0 < valid_fraction <= 1.0:
        raise ParameterError("valid_fraction", valid_fraction, "must be in (0, 1]")
    if cycle_s < 0.0 or ring_check_s < 0.0:
        raise ParameterError("cycle_s", (cycle_s, ring_check_s), "times must be >= 0")
    rows = []
    for n in range(1, max_hits + 1):
        u = mean_u(per_hit, n, output)
        shots = math.ceil(n / valid_fraction - 1e-9)
        rows.append(
            TradeoffRow(n, u, per_hit.coverage_k * u, shots, lab_time_s(shots, cycle_s, ring_check_s))
        )
    return rows


def hits_needed(per_hit: Budget, target_U: float, output: str = "bbcor") -> int | None:
    """Fewest like hits whose mean has U <= target_U; None if the systematic floor is above it."""
    rand, sys = _per_hit(per_hit, output)
    room = (target_U / per_hit.coverage_k) ** 2 - sys
    if room <= 0.0:
        return None
    n = max(1, math.ceil(rand / room))
    # guard the ceiling against rounding either way
    while n > 1 and mean_u(per_hit, n - 1, output) * per_hit.coverage_k <= target_U:
        n -= 1
    while mean_u(per_hit, n, output) * per_hit.coverage_k > target_U:
        n += 1
    return n
