"""Study harnesses live in benchmarks/, not in the product.

The package keeps the models and what they measure (errors, costs per call); reading the machine
(/proc/cpuinfo, the load average), pausing the garbage collector around timed batches, and
starting processes to write documents belong to the benchmark harness.
"""

from __future__ import annotations

import gc
import re
from pathlib import Path

from benchmarks.timing import best_time, load_average, machine
from rig.physics.precision import work_precision

ROOT = Path(__file__).resolve().parents[2]
HARNESS = re.compile(r"^\s*import (gc|subprocess)\b|getloadavg|/proc/cpuinfo|from subprocess ", re.MULTILINE)


def test_the_product_neither_reads_the_machine_nor_starts_processes_for_studies() -> None:
    found = [
        str(path.relative_to(ROOT))
        for package in ("rig/physics", "rig/report")
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
    study = work_precision(quick=True, timer=best_time, methods=("rig-DOP853",))
    assert all(r.time_s > 0 for r in study.rows)
    assert "cpu" not in study.environment  # the package does not read /proc/cpuinfo
    assert before is None or len(before) == 3
