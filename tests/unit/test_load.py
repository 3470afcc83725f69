"""The load harness (tests/load.py): it really burns CPU, and it never leaves a process behind."""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests import load
from tests.load import ROOT_ENV, burners_to_spin, cpu_load, cpu_seconds, running_beside

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


SPIN = "import time\nend = time.monotonic() + 60\nwhile time.monotonic() < end: pass"


def _spinner(detached: bool = False) -> int:
    """A busy Python loop for at most 60 s: a child of this process, or (detached) of nobody here."""
    spin = [sys.executable, "-c", SPIN]
    if not detached:
        return subprocess.Popen(spin).pid
    line = " ".join(shlex.quote(a) for a in spin)
    out = subprocess.run(["sh", "-c", f"{line} >/dev/null 2>&1 & echo $!"], capture_output=True, text=True)
    return int(out.stdout)


def _stop(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 10
    while not _gone(pid) and time.monotonic() < deadline:
        try:
            os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            time.sleep(0.02)


def _block_in_child(seconds: float, root: int) -> subprocess.Popen[str]:
    """A child process that holds a load block for `seconds`, the test run rooted at `root`, and
    prints the block's report line."""
    code = (
        "import time\nfrom tests.load import LAST_BLOCK, cpu_load\n"
        f"with cpu_load():\n    time.sleep({seconds})\nprint(LAST_BLOCK[0], flush=True)\n"
    )
    env = {**os.environ, ROOT_ENV: str(root)}
    return subprocess.Popen(
        [sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, text=True, env=env
    )


def _field(line: str, name: str) -> float:
    return float(line.split(name + " ")[1].split()[0].rstrip(","))


def test_what_runs_beside_the_test_is_told_from_its_own_processes() -> None:
    """Seen from one child of the test run's root: another busy child is beside it, its own busy
    process is its own, and a busy process outside the run (left to init) is neither."""
    mine, other, stranger = _spinner(), _spinner(), _spinner(detached=True)
    try:
        deadline = time.monotonic() + 30  # a runnable process is 'R' even while it waits for a CPU
        while time.monotonic() < deadline:
            beside, running_mine = running_beside(mine, os.getpid())
            if mine in running_mine and other in beside:
                break
            time.sleep(0.05)
        assert mine in running_mine and mine not in beside
        assert other in beside
        assert stranger not in beside and stranger not in running_mine
    finally:
        for pid in (mine, other, stranger):
            _stop(pid)


def test_with_nothing_beside_both_burners_spin(monkeypatch: pytest.MonkeyPatch) -> None:
    """The test run is this process alone: nothing else counts, so both burners spin, each taking
    about the share of the CPU that a busy process of the test's own gets."""
    monkeypatch.setenv(ROOT_ENV, str(os.getpid()))
    reference = _spinner()  # the test's own: no load beside it
    try:
        with cpu_load() as procs:
            pids = [p.pid for p in procs] + [reference]
            start = [cpu_seconds(pid) for pid in pids]
            time.sleep(2.0)
            used = [cpu_seconds(pid) - s for pid, s in zip(pids, start, strict=True)]
    finally:
        _stop(reference)
    assert min(used[:2]) >= 0.5 * used[2], used


def test_burners_fill_in_only_for_what_is_missing() -> None:
    """Two busy processes of the test run beside the block: its burners mostly wait, and the count
    beside it, burners included, stays at two or more."""
    others = [_spinner() for _ in range(2)]
    try:
        block = _block_in_child(2.0, os.getpid())
        line = block.communicate(timeout=120)[0].strip()
    finally:
        for pid in others:
            _stop(pid)
    assert block.returncode == 0, line
    assert _field(line, "burners") < 0.5, line  # spinning burners would show 2
    assert _field(line, "beside") >= 2.0, line


def test_two_blocks_at_once_do_not_double_the_load() -> None:
    """Two test processes in a load block at the same time (parallel workers): each counts the
    other's burners as load beside it, so between them about two burners spin, not four."""
    children = [_block_in_child(3.0, os.getpid()) for _ in range(2)]
    lines = [c.communicate(timeout=120)[0].strip() for c in children]
    assert all(c.returncode == 0 for c in children), lines
    assert all(_field(line, "beside") >= 2.0 for line in lines), lines
    assert sum(_field(line, "burners") for line in lines) <= 2.8, lines  # four if each ignored the other
    with cpu_load(n=1) as outer, cpu_load(n=1) as inner:  # blocks inside blocks: both live
        assert outer[0].poll() is None and inner[0].poll() is None


def test_a_burner_starts_at_once_and_waits_only_after_a_steady_count() -> None:
    assert burners_to_spin(2, [2, 2, 2], 0.0) == 0
    assert burners_to_spin(2, [2, 2, 0], 0.0) == 2  # a neighbour gone: both spin at the next tick
    assert burners_to_spin(2, [0, 2, 2], 0.0) == 2  # back for two ticks only: not yet
    assert burners_to_spin(2, [1, 2, 2, 2], 0.0) == 0  # steady for three ticks: both wait
    assert burners_to_spin(2, [2, 1, 2], 0.0) == 1
    assert burners_to_spin(2, [2, 2, 2], -0.5) == 2  # short on average: all spin
    assert burners_to_spin(2, [], 0.0) == 2
    assert burners_to_spin(2, [5, 7, 9], 0.0) == 0


def test_a_failed_governor_spins_every_burner_and_the_block_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def failing(own: int, root: int) -> tuple[list[int], list[int]]:
        calls.append(own)
        if len(calls) > 1:
            raise OSError("no /proc")
        return list(range(100, 110)), []  # ten beside: the burners wait

    monkeypatch.setattr(load, "running_beside", failing)
    with pytest.raises(RuntimeError, match=r"load governor failed.*no /proc"), cpu_load() as procs:
        deadline = time.monotonic() + 30
        while len(calls) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        start = [cpu_seconds(p.pid) for p in procs]
        time.sleep(1.0)
        used = [cpu_seconds(p.pid) - s for p, s in zip(procs, start, strict=True)]
    assert min(used) > 0.05, used  # spinning again after the failure
    assert all(_gone(p.pid) for p in procs)
