"""The timing harness of the studies: careful timing and a description of the machine.

The studies' harness times a solve (studies.accuracy.stopwatch: Stopwatch, time_per_call); this
one adds what only a study needs: the garbage collector paused inside timed batches (as timeit
does), the CPU model, the load average and numba's threading set-up, without which timings mean
little.
"""

from __future__ import annotations

import gc
import json
import os
import platform
import subprocess
import sys
from collections.abc import Callable
from typing import Any

from studies.accuracy.stopwatch import MIN_TIMED_S, Stopwatch, best_batch, calls_per_batch, versions


def paused_batch(solve: Callable[[], object], repeats: int, number: int) -> float:
    """`best_batch` with the collector paused (a collection inside one batch is noise, not solver cost)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        return best_batch(solve, repeats, number)
    finally:
        if enabled:
            gc.enable()


def best_time(
    solve: Callable[[], object], repeats: int, min_time_s: float = MIN_TIMED_S, once_s: float | None = None
) -> float:
    """`time_per_call` with the collector paused during the timed batches; a calibrating call, if
    one is needed, runs before the pause."""
    return paused_batch(solve, repeats, calls_per_batch(solve, min_time_s, once_s))


def careful(repeats: int, min_time_s: float = MIN_TIMED_S) -> Stopwatch:
    """The study's stopwatch with the collector paused inside the timed batches."""
    return Stopwatch(repeats, min_time_s, batch=paused_batch)


def load_average() -> list[float] | None:
    """1, 5 and 15 minute load averages (None where unsupported): other work skews the timings."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def cpu_model() -> str:
    """The CPU's name (platform.processor() is empty on most Linux systems; /proc/cpuinfo names it)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine() -> dict[str, Any]:
    """The package's versions plus the machine: CPU, usable CPUs, numba threading, OpenMP policy."""
    import numba

    env = versions()
    env["cpu"] = cpu_model()
    if hasattr(os, "sched_getaffinity"):
        env["cpus_usable"] = len(os.sched_getaffinity(0))
    # Parallel batches (cor_grid) depend on numba's threading layer and OpenMP's wait policy.
    try:
        env["numba_threading_layer"] = numba.threading_layer()
    except ValueError:  # no parallel region has run yet in this process
        env["numba_threading_layer"] = "not started"
    env["numba_threads"] = numba.get_num_threads()
    env["omp_wait_policy"] = os.environ.get("OMP_WAIT_POLICY", "unset")
    return env


_PROBE = """
import json, statistics, sys, time
import numpy as np
from rig.physics import fast
from rig.physics.curve import cor_grid
from rig.physics.params import DEFAULT_PARAMS
fast.warm_up()
hoops = np.linspace(300.0, 20000.0, int(sys.argv[1]))
cor_grid(DEFAULT_PARAMS, 60.8, hoops, 1e-8)
ts = []
for _ in range(40):
    t0 = time.perf_counter(); cor_grid(DEFAULT_PARAMS, 60.8, hoops, 1e-8); ts.append(time.perf_counter() - t0)
print(json.dumps([min(ts), statistics.median(ts)]))
"""


def parallel_call_probe(points: int = 25) -> dict[str, list[float] | None]:
    """Min and median seconds of one cor_grid call in fresh processes, per OpenMP wait policy."""
    # numba's OpenMP layer (libgomp) lets idle workers spin and then sleep; how long waking them
    # takes depends on the policy and on other load. A fresh process per setting, since the policy
    # is read once when the runtime starts.
    out: dict[str, list[float] | None] = {}
    for name, extra in (("default", {}), ("OMP_WAIT_POLICY=passive", {"OMP_WAIT_POLICY": "passive"})):
        env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"} | extra
        try:
            done = subprocess.run(
                [sys.executable, "-c", _PROBE, str(points)],
                env=env,
                capture_output=True,
                text=True,
                timeout=120,
                check=True,
            )
            out[name] = json.loads(done.stdout.strip().splitlines()[-1])
        except (subprocess.SubprocessError, OSError, ValueError, IndexError):
            out[name] = None
    return out
