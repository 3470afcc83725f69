"""The measurement harness of the solver-accuracy study: how long a solve takes, on what.

`rig-study accuracy` and benchmarks/accuracy_* time the work-precision sweeps
(studies.accuracy.precision, studies.accuracy.curve_cost) with a `Stopwatch` from here and stamp
the study with the interpreter and library versions. Certification never imports this module (an
import-linter contract says so): the sweeps themselves compute errors and function-evaluation
counts, which do not depend on the machine; only the times come from here. The careful variant
(collector paused, CPU model and load recorded) is benchmarks/timing.py.
"""

from __future__ import annotations

import dataclasses
import math
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from rig.core.errors import ParameterError
from studies.accuracy.precision import PrecisionStudy

MIN_TIMED_S = 0.01  # a timed batch of solves lasts at least this long (perf_counter resolution, jitter)
QUICK_MIN_TIMED_S = 0.002
MAX_LOOP = 2000

R = TypeVar("R")
Batch = Callable[[Callable[[], object], int, int], float]
"""(solve, repeats, number) -> seconds per call of the fastest batch."""


def versions() -> dict[str, Any]:
    """Interpreter and library versions: timings mean nothing without them (the machine itself is
    described by the benchmark harness)."""
    import numba
    import scipy

    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
    }


def calls_per_batch(solve: Callable[[], object], min_time_s: float, once_s: float | None = None) -> int:
    """How many calls make a timed batch last `min_time_s` (well above the timer's resolution).

    once_s: the duration of one earlier call, if known; it sizes the loop instead of a calibrating call.
    """
    once = once_s
    if once is None or once < min_time_s:
        t0 = time.perf_counter()
        solve()
        once = time.perf_counter() - t0
    return max(1, min(MAX_LOOP, math.ceil(min_time_s / max(once, 1e-9))))


def best_batch(solve: Callable[[], object], repeats: int, number: int) -> float:
    """Seconds per call of the fastest of `repeats` batches of `number` calls."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(number):
            solve()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def time_per_call(
    solve: Callable[[], object], repeats: int, min_time_s: float = MIN_TIMED_S, once_s: float | None = None
) -> float:
    """Best-of-`repeats` seconds per call of `solve` (already warmed up); fast calls are looped."""
    return best_batch(solve, repeats, calls_per_batch(solve, min_time_s, once_s))


@dataclass(frozen=True)
class Stopwatch:
    """Times a solve for the sweeps: one warm-up call (its result is returned), then the best of
    `repeats` batches, each looped to last at least `min_time_s`."""

    repeats: int = 5
    min_time_s: float = MIN_TIMED_S
    batch: Batch = best_batch  # benchmarks/timing.py passes one that pauses the collector

    def __post_init__(self) -> None:
        if not isinstance(self.repeats, int) or isinstance(self.repeats, bool) or self.repeats < 1:
            raise ParameterError("repeats", self.repeats, "must be a whole number >= 1")
        if not self.min_time_s > 0.0:
            raise ParameterError("min_time_s", self.min_time_s, "must be > 0 s")

    def __call__(self, solve: Callable[[], R]) -> tuple[R, float]:
        """(result of the warm-up call, best seconds per call)."""
        t0 = time.perf_counter()
        result = solve()
        once = time.perf_counter() - t0
        return result, self.batch(solve, self.repeats, calls_per_batch(solve, self.min_time_s, once))


def stopwatch(quick: bool = False, repeats: int = 5) -> Stopwatch:
    """The study's stopwatch: `repeats` batches of >= 10 ms; quick: one batch of >= 2 ms (a smoke run)."""
    return Stopwatch(1, QUICK_MIN_TIMED_S) if quick else Stopwatch(repeats, MIN_TIMED_S)


def stamped(run: Callable[[], PrecisionStudy]) -> PrecisionStudy:
    """Run a study and record the versions it ran on and its wall time."""
    started = time.perf_counter()
    study = run()
    return dataclasses.replace(study, environment=versions(), elapsed_s=time.perf_counter() - started)


__all__ = [
    "MIN_TIMED_S",
    "QUICK_MIN_TIMED_S",
    "Stopwatch",
    "best_batch",
    "calls_per_batch",
    "stamped",
    "stopwatch",
    "time_per_call",
    "versions",
]
