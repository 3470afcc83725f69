"""Study harnesses live apart from the product.

The sweeps (studies.accuracy) and the product's models compute what does not depend on the
machine (errors, evaluation counts); the clock comes from studies.accuracy.stopwatch (the accuracy
study's stopwatch, injected); reading the machine (/proc/cpuinfo, the load average), pausing the
garbage collector around timed batches, and starting processes to write documents belong to the
benchmark harness.
"""

from __future__ import annotations

import gc
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from benchmarks.timing import best_time, careful, load_average, machine
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS
from rig.physics.reference import solve_reference
from studies.accuracy.curve_cost import curve_tradeoff
from studies.accuracy.precision import work_precision
from studies.accuracy.stopwatch import Stopwatch, stamped

ROOT = Path(__file__).resolve().parents[2]
HARNESS = re.compile(r"^\s*import (gc|subprocess)\b|getloadavg|/proc/cpuinfo|from subprocess ", re.MULTILINE)
CLOCK = re.compile(r"^\s*(import time\b|from time import)|perf_counter|monotonic\(", re.MULTILINE)


class FakeTimer:
    """Times nothing: counts the solves it is handed and reports a fixed cost for each."""

    def __init__(self, repeats: int, seconds: float) -> None:
        self.repeats = repeats
        self.seconds = seconds
        self.handed = 0

    def __call__(self, solve: Callable[[], Any]) -> tuple[Any, float]:
        self.handed += 1
        return solve(), self.seconds


def test_the_product_neither_reads_the_machine_nor_starts_processes_for_studies() -> None:
    found = [
        str(path.relative_to(ROOT))
        for package in ("rig/physics", "rig/report", "studies")
        for path in sorted((ROOT / package).rglob("*.py"))
        if HARNESS.search(path.read_text())
    ]
    assert found == []


def test_best_time_pauses_the_collector_during_batches_and_restores_it() -> None:
    seen: list[bool] = []
    assert gc.isenabled()
    t = best_time(lambda: seen.append(gc.isenabled()), repeats=3, min_time_s=1e-3)
    assert 0.0 < t < 1e-3
    assert len(seen) > 3 * 2
    assert seen[0] is True  # the calibrating call, outside the batches
    assert not any(seen[1:])
    assert gc.isenabled()


def test_machine_names_the_cpu_and_the_load() -> None:
    env = machine()
    assert isinstance(env["cpu"], str) and env["cpu"]
    assert env["cpu_count"] >= 1
    load = load_average()
    assert load is None or (len(load) == 3 and all(x >= 0 for x in load))


def test_the_harness_times_and_describes_a_study() -> None:
    before = load_average()
    study = stamped(lambda: work_precision(quick=True, timer=careful(1, 1e-3), methods=("rig-DOP853",)))
    assert all(r.time_s > 0 for r in study.rows)
    assert study.repeats == 1 and study.elapsed_s > 0
    assert {"python", "numpy", "scipy", "numba"} <= set(study.environment)
    assert "cpu" not in study.environment  # the package does not read /proc/cpuinfo
    assert before is None or len(before) == 3


def test_the_sweeps_read_no_clock() -> None:
    sweeps = [p for p in sorted((ROOT / "studies" / "accuracy").glob("*.py")) if p.name != "stopwatch.py"]
    assert len(sweeps) >= 4  # precision, curve_cost, first_step, plots: moved out of rig/, still checked
    found = [
        str(path.relative_to(ROOT))
        for package in ("rig/physics", "rig/report", "rig/measure")
        for path in sorted((ROOT / package).rglob("*.py"))
        if CLOCK.search(path.read_text())
    ] + [str(path.relative_to(ROOT)) for path in sweeps if CLOCK.search(path.read_text())]
    assert found == []


def test_an_untimed_sweep_has_the_errors_and_counts_and_no_times() -> None:
    rtols = (1e-5, 1e-8)
    study = work_precision(methods=("rig-DOP853", "RK45"), hoops=(1250.0,), rtols=rtols)
    imp = Impact(DEFAULT_PARAMS, 60.8, 1250.0)
    ref = solve_reference(imp, method="DOP853", rtol=1e-13, first_step="scipy")
    assert study.repeats == 0 and math.isnan(study.elapsed_s) and study.environment == {}
    assert len(study.rows) == 4
    for r in study.rows:
        assert math.isnan(r.time_s)
        # errors and counts from solves made here, outside the sweep
        if r.method == "rig-DOP853":
            direct = fast.solve(imp, r.rtol)
        else:
            direct = solve_reference(imp, method="RK45", rtol=r.rtol, first_step="scipy")
        assert r.nfev == direct.nfev
        assert r.cor_error == pytest.approx(abs(direct.cor - ref.cor), rel=1e-12, abs=1e-15)


def test_the_injected_timer_is_the_only_source_of_times() -> None:
    timer = FakeTimer(repeats=3, seconds=0.125)
    study = work_precision(methods=("rig-DOP853",), hoops=(1250.0,), rtols=(1e-6, 1e-9), timer=timer)
    assert timer.handed == 2  # one solve per row, each handed to the timer exactly once
    assert [r.time_s for r in study.rows] == [0.125, 0.125]
    assert study.repeats == 3
    curve_timer = FakeTimer(repeats=1, seconds=0.5)
    rows = curve_tradeoff(quick=True, timer=curve_timer)
    assert curve_timer.handed == 2 * len(rows)  # the whole curve and the grid alone, per row
    assert all(r.time_s == 0.5 and r.grid_time_s == 0.5 for r in rows)
    assert all(math.isnan(r.time_s) and math.isnan(r.grid_time_s) for r in curve_tradeoff(quick=True))


def test_the_stopwatch_returns_the_warm_up_result_and_loops_fast_calls() -> None:
    calls: list[int] = []

    def solve() -> int:
        calls.append(1)
        return len(calls)

    first, seconds = Stopwatch(repeats=3, min_time_s=1e-3)(solve)
    assert first == 1  # the warm-up call's result, not a later one
    assert 0.0 < seconds < 1e-3
    assert len(calls) > 1 + 3 * 2  # the warm-up, then three batches of several calls


def test_the_careful_stopwatch_pauses_the_collector_only_in_batches() -> None:
    seen: list[bool] = []
    careful(2, 1e-3)(lambda: seen.append(gc.isenabled()))
    k = seen.index(False)  # the warm-up (and a calibrating call if it was too quick) run collected
    assert 1 <= k <= 2 and len(seen) > k + 2 and not any(seen[k:])
    assert gc.isenabled()
