"""The load harness (tests/load.py): it really burns CPU, and it never leaves a process behind."""

from __future__ import annotations

import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.load import LAST_BLOCK, cpu_load, cpu_seconds, running_beside

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
    with cpu_load(fill=False) as procs:
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


def test_two_blocks_at_once_do_not_double_the_load() -> None:
    """Two test processes in a load block at the same time (parallel workers): each counts the
    other's burners as load beside it, so between them about two burners spin, not four, and each
    still has two or more processes beside it on average."""
    code = (
        "import time\nfrom tests.load import LAST_BLOCK, cpu_load\n"
        "with cpu_load():\n    time.sleep(3.0)\nprint(LAST_BLOCK[0], flush=True)\n"
    )
    children = [
        subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    lines = [c.communicate(timeout=120)[0].strip() for c in children]
    assert all(c.returncode == 0 for c in children), lines
    beside = [float(line.split("beside ")[1].split()[0]) for line in lines]
    burners = [float(line.split("burners ")[1]) for line in lines]
    assert all(b >= 2.0 for b in beside), lines
    assert sum(burners) <= 2.6, lines  # four would spin if each block ignored the other
    with cpu_load(n=1) as outer, cpu_load(n=1) as inner:  # blocks inside blocks: both live
        assert outer[0].poll() is None and inner[0].poll() is None


def _spinner(detached: bool) -> int:
    """A busy shell loop for at most 60 s: a child of this process, or (detached) of nobody here."""
    spin = [
        sys.executable,
        "-c",
        "import time\nend = time.monotonic() + 60\nwhile time.monotonic() < end: pass",
    ]
    if not detached:
        return subprocess.Popen(spin).pid
    line = " ".join(shlex.quote(a) for a in spin)
    out = subprocess.run(["sh", "-c", f"{line} >/dev/null 2>&1 & echo $!"], capture_output=True, text=True)
    return int(out.stdout)


def _stop(pid: int) -> None:
    import os
    import signal

    os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 10
    while not _gone(pid) and time.monotonic() < deadline:
        try:
            os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            time.sleep(0.02)


def test_what_runs_beside_the_test_is_told_from_its_own_processes() -> None:
    """A busy child of the test is the test's own; a busy process outside its tree is load beside it."""
    import os

    mine, other = _spinner(detached=False), _spinner(detached=True)
    try:
        deadline = time.monotonic() + 30  # a runnable process is 'R' even while it waits for a CPU
        while time.monotonic() < deadline:
            _, running_mine = running_beside(os.getpid())
            if mine in running_mine:
                break
            time.sleep(0.05)
        assert mine in running_mine
        assert other not in running_mine
        beside_without, _ = running_beside(mine)  # seen from the other side: `other` is beside `mine`'s tree
        assert beside_without >= 1
    finally:
        _stop(mine)
        _stop(other)


def test_burners_fill_in_only_for_what_is_missing() -> None:
    """With two busy processes already beside the test, the burners mostly wait; the block's count
    beside the test (burners included) averages at least two either way."""
    others = [_spinner(detached=True) for _ in range(2)]
    try:
        with cpu_load() as procs:
            pids = [p.pid for p in procs]
            start = [cpu_seconds(pid) for pid in pids + others]
            time.sleep(2.0)
            used = [cpu_seconds(pid) - s for pid, s in zip(pids + others, start, strict=True)]
    finally:
        for pid in others:
            _stop(pid)
    # spinning burners would have had the spinners' share of the CPU, however busy the machine
    assert sum(used[:2]) < 0.3 * sum(used[2:]), used
    (line,) = LAST_BLOCK
    mean = float(line.split("beside ")[1].split()[0])
    assert mean >= 2.0, line
