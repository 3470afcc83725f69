"""The load harness (tests/load.py): it really burns CPU, and it never leaves a process behind."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.load import cpu_load, cpu_seconds

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def _gone(pid: int) -> bool:
    """No such process, or only a zombie awaiting its reaper."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def test_two_burners_use_cpu_and_are_reaped_after_the_block() -> None:
    with cpu_load() as procs:
        assert len(procs) == 2 and all(p.poll() is None for p in procs)
        # they spin: together they use a CPU second, which idle processes never would; on a shared
        # machine, however busy, that only takes longer (a share of the CPU per wall second is not
        # a measure here: 0.25 was seen with the load at 9 on 2 cores)
        start = sum(cpu_seconds(p.pid) for p in procs)
        deadline = time.monotonic() + 240.0
        while sum(cpu_seconds(p.pid) for p in procs) - start < 1.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert sum(cpu_seconds(p.pid) for p in procs) - start >= 1.0
    assert all(p.returncode is not None for p in procs)
    assert all(_gone(p.pid) for p in procs)


def test_burners_are_killed_when_the_block_raises() -> None:
    with pytest.raises(RuntimeError, match="boom"), cpu_load() as procs:
        raise RuntimeError("boom")
    assert all(p.returncode is not None and _gone(p.pid) for p in procs)


def test_a_burner_stops_by_itself_at_its_time_limit() -> None:
    with cpu_load(n=1, limit_s=0.3) as (proc,):
        assert proc.wait(timeout=30) == 0  # ended on its own, not killed


def test_burners_outlive_no_killed_parent() -> None:
    """A test process killed with SIGKILL cannot clean up: its burners notice and stop."""
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from tests.load import cpu_load\n"
            "with cpu_load() as procs:\n"
            "    print(*[p.pid for p in procs], flush=True)\n"
            "    input()\n",
        ],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None
    pids = [int(p) for p in child.stdout.readline().split()]
    assert len(pids) == 2 and not any(_gone(p) for p in pids)
    child.kill()
    child.wait()
    deadline = time.monotonic() + 20
    while not all(_gone(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(p) for p in pids)


def test_burners_take_turns_between_processes() -> None:
    """While one process runs burners, another cannot take the load lock (a parallel test worker
    waits); a block inside a block of the same process does not wait for itself."""
    import fcntl
    import os

    from tests.load import lock_path

    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys\nfrom tests.load import cpu_load\n"
            "with cpu_load(n=1):\n    print('in', flush=True)\n    sys.stdin.read()\n",
        ],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None and child.stdin is not None
    try:
        assert child.stdout.readline().strip() == "in"
        fd = os.open(lock_path(), os.O_RDWR)
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)
    finally:
        child.stdin.close()
        assert child.wait(timeout=60) == 0
    with cpu_load(n=1) as outer, cpu_load(n=1) as inner:  # returns: the inner block took no lock
        assert outer[0].poll() is None and inner[0].poll() is None
