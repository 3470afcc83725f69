"""Machine load beside a test: CPU-bound processes, bounded in time, always cleaned up.

Anything that crosses a process boundary must still pass with two CPU-bound processes running
beside it (a shared lab PC, a CI runner doing other jobs). `cpu_load()` starts them:

    with cpu_load():            # two burners, each gone after at most LIMIT_S
        ...

Each burner spins in pure Python until its deadline, or until its parent is gone (so a test
process killed with SIGKILL does not leave it behind), whichever comes first. Leaving the block,
normally or by an exception, kills and reaps every burner. The pytest fixture `cpu_load` in
tests/conftest.py wraps this for a whole test.

Burners fill in, they do not pile on: what a test needs is `n` CPU-bound processes beside it, and in
a parallel run the other test workers (and the processes they start, burners of their own included)
often are that already. Every TICK_S a thread of the block counts the running processes on the
machine that are neither the test's own (its process and every descendant, but for the burners of
its other blocks) nor this block's burners, and lets as many burners spin as that count falls short
of `n` (all of them on an otherwise idle machine); a shortfall is made up in the next ticks, so over
the block the count beside the test, burners included, averages at least `n`. The others wait on
the control file, checking it, the deadline and their parent every 10 ms. So parallel test workers
need no turns: two blocks at once keep `n` burners spinning between them, not 2 `n`.
`fill=False` keeps every burner spinning. RIG_TEST_LOAD_LOG=FILE appends one line per block: its
length, the mean number of running processes beside the test and the share of ticks it was `n` or
more, and the burners' mean.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator

BURNERS = 2
LIMIT_S = 300.0  # no test that needs load runs longer; a burner never outlives this

TICK_S = 0.05  # how often the block counts the processes beside the test

# A busy loop in slices of ~10 ms; before each it checks the deadline, that its parent still exists
# and its turn: it spins while the number in the control file exceeds its index, else sleeps 10 ms.
_BURN = """
import os, sys, time
deadline, parent = time.monotonic() + float(sys.argv[1]), os.getppid()
control, index = sys.argv[2], int(sys.argv[3])
print("burning", flush=True)
while time.monotonic() < deadline and os.getppid() == parent:
    try:
        with open(control, "rb") as f:
            turn = int(f.read(1) or b"9") > index
    except (OSError, ValueError):
        turn = True
    if not turn:
        time.sleep(0.01)
        continue
    n = 0
    for i in range(50_000):
        n += i * i
"""


def running_beside(own: int) -> tuple[int, list[int]]:
    """(running processes that are not `own` or its descendants, the running descendants' pids), from
    one pass over /proc (a process's state is its main thread's: 'R', running or runnable)."""
    parent: dict[int, int] = {}
    running: set[int] = set()
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
        except OSError:
            continue  # gone meanwhile
        pid = int(name)
        parent[pid] = int(fields[1])
        if fields[0] == b"R":
            running.add(pid)
    mine = {own}
    grew = True
    while grew:
        grew = False
        for pid, ppid in parent.items():
            if ppid in mine and pid not in mine:
                mine.add(pid)
                grew = True
    return len(running - mine), sorted(running & mine)


class _Governor(threading.Thread):
    """Every TICK_S: counts the running processes beside the test and writes how many burners spin."""

    def __init__(self, n: int, control: int, burners: list[int]) -> None:
        super().__init__(daemon=True)
        self.n, self.control, self.burners = n, control, set(burners)
        self.done = threading.Event()
        self.beside: list[int] = []  # each tick's count beside the test, burners included
        self.spinning: list[int] = []

    def run(self) -> None:
        credit = 0.0  # process-ticks beside the test above n so far (below 0: a shortfall to make up)
        while True:
            others, mine = running_beside(os.getpid())
            spinning = len(self.burners.intersection(mine))
            others += len(_ACTIVE.intersection(mine) - self.burners)  # this process's other blocks
            self.beside.append(others + spinning)
            self.spinning.append(spinning)
            credit += others + spinning - self.n
            turn = self.n if credit < 0 else max(0, min(self.n, self.n - others))
            os.pwrite(self.control, str(turn).encode(), 0)
            if self.done.wait(TICK_S):
                return

    def report(self, seconds: float) -> str:
        """One line: the block's length, the mean count beside it, the share of ticks at n or more."""
        ticks = max(1, len(self.beside))
        mean = sum(self.beside) / ticks
        met = sum(b >= self.n for b in self.beside) / ticks
        burners = sum(self.spinning) / ticks
        return (
            f"{seconds:.2f} s, {ticks} ticks:"
            f" beside {mean:.2f} (>= {self.n}: {met:.0%}), burners {burners:.2f}"
        )


LAST_BLOCK: list[str] = []  # the last block's report line (tests/unit/test_load.py reads it)
_ACTIVE: set[int] = set()  # the burners of every block open in this process


@contextlib.contextmanager
def cpu_load(
    n: int = BURNERS, limit_s: float = LIMIT_S, fill: bool = True
) -> Iterator[list[subprocess.Popen[str]]]:
    """Keep `n` CPU-bound processes beside the block for at most `limit_s` s, burners filling in for
    what else runs (all `n` spin with fill=False); yield the burners."""
    with tempfile.TemporaryFile() as control_file:
        control = control_file.fileno()
        os.pwrite(control, str(n).encode(), 0)  # every burner spins until the first count
        procs: list[subprocess.Popen[str]] = []
        governor: _Governor | None = None
        started = time.monotonic()
        try:
            for index in range(n):
                procs.append(
                    subprocess.Popen(
                        [
                            sys.executable,
                            "-c",
                            _BURN,
                            repr(limit_s),
                            f"/proc/{os.getpid()}/fd/{control}",
                            str(index),
                        ],
                        stdin=subprocess.DEVNULL,
                        stdout=subprocess.PIPE,
                        stderr=subprocess.DEVNULL,
                        text=True,
                    )
                )
            for proc in procs:  # each one is running before the block starts
                assert proc.stdout is not None
                if proc.stdout.readline().strip() != "burning":
                    raise RuntimeError(f"load process {proc.pid} did not start (exit {proc.poll()})")
            _ACTIVE.update(p.pid for p in procs)
            if fill:
                governor = _Governor(n, control, [p.pid for p in procs])
                governor.start()
            yield procs
        finally:
            if governor is not None:
                governor.done.set()
                governor.join()
                line = governor.report(time.monotonic() - started)
                LAST_BLOCK[:] = [line]
                if log := os.environ.get("RIG_TEST_LOAD_LOG"):
                    with open(log, "a", encoding="utf-8") as out:
                        out.write(line + "\n")
            _ACTIVE.difference_update(p.pid for p in procs)
            for proc in procs:
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
            for proc in procs:
                proc.wait()
                if proc.stdout is not None:
                    proc.stdout.close()


def cpu_seconds(pid: int) -> float:
    """User + system CPU time a running process has used, s (Linux /proc)."""
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def stop_group(proc: subprocess.Popen[str], timeout_s: float = 10.0) -> None:
    """Ctrl-C a child's process group (as a terminal would), then kill it if it does not end."""
    import signal

    os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
