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
often are that already. Every TICK_S a thread of the block counts the running processes of the test
run (the descendants of the process RIG_TEST_LOAD_ROOT names, which tests/conftest.py sets to the
pytest controller) that are not the test's own (its process and every descendant, but for the
burners of its other blocks), and lets as many burners spin as that count falls short of `n`. A
burner starts at once (within a tick) and waits again only after the count was high enough on
HOLD_TICKS ticks in a row; while the block is short of `n` on average, every burner spins; if the
thread fails, every burner spins and the block raises. Outside a test run (no root set) nothing else
counts and every burner spins, as it does with `fill=False`. The waiting burners check the control
file, the deadline and their parent every 10 ms. Parallel workers need no turns: two blocks at once
keep about `n` burners spinning between them, not 2 `n`. RIG_TEST_LOAD_LOG=FILE appends one line
per block: its length, the mean count beside the test (burners included), the share of ticks with
`n` or more, and the burners' mean.
"""

from __future__ import annotations

import contextlib
import os
import random
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
            turn = (f.read(1) or b"\\xff")[0] > index
    except OSError:
        turn = True
    if not turn:
        time.sleep(0.01)
        continue
    n = 0
    for i in range(50_000):
        n += i * i
"""


ROOT_ENV = "RIG_TEST_LOAD_ROOT"  # the test run's first process (tests/conftest.py sets it)
HOLD_TICKS = 3  # a burner waits only once the count beside was high enough for this many ticks


def load_root() -> int:
    """The process whose descendants make up the test run (the pytest controller and its workers);
    this process when it is not set, so that nothing else counts and every burner spins."""
    try:
        return int(os.environ[ROOT_ENV])
    except (KeyError, ValueError):
        return os.getpid()


def running_beside(own: int, root: int) -> tuple[list[int], list[int]]:
    """(the running descendants of `root` that are not `own` or its descendants, the running ones
    that are), from one pass over /proc: only the test run's own processes count as load, not a
    server it left to init, a kernel thread or another user's work (on a busy machine that errs
    towards more load). A process's state is its main thread's: 'R', running or runnable."""
    children: dict[int, list[int]] = {}
    running: set[int] = set()
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            fields = _stat(int(name))
        except OSError:
            continue  # gone meanwhile
        pid = int(name)
        children.setdefault(int(fields[1]), []).append(pid)
        if fields[0] == "R":
            running.add(pid)

    def tree(top: int) -> set[int]:
        seen, todo = {top}, [top]
        while todo:
            for child in children.get(todo.pop(), ()):
                if child not in seen:
                    seen.add(child)
                    todo.append(child)
        return seen

    mine = tree(own)
    run = tree(root) if root != own else mine
    return sorted((run - mine) & running), sorted(mine & running)


def burners_to_spin(n: int, recent: list[int], credit: float) -> int:
    """How many of `n` burners spin, from the counts beside the test (burners aside) of the last
    HOLD_TICKS ticks, the newest last: at once as many as the newest count falls short of `n`, but
    one waits only when the count was high enough on every recent tick (a neighbour that comes and
    goes leaves no gap); all of them while the block is short of `n` on average (credit < 0)."""
    if credit < 0 or not recent:
        return n
    return max(0, min(n, n - min(recent[-HOLD_TICKS:])))


class _Governor(threading.Thread):
    """Every TICK_S (jittered, so that two blocks do not tick in step): counts the running processes
    beside the test and writes how many burners spin; if it fails, every burner spins."""

    def __init__(self, n: int, control: int, burners: list[int]) -> None:
        super().__init__(daemon=True)
        self.n, self.control, self.burners = n, control, set(burners)
        self.done = threading.Event()
        self.failed: BaseException | None = None
        self.beside: list[int] = []  # each tick's count beside the test, burners included
        self.spinning: list[int] = []

    def run(self) -> None:
        try:
            self._govern()
        except BaseException as exc:  # reported by cpu_load, after every burner spins
            self.failed = exc
            os.pwrite(self.control, bytes([self.n]), 0)

    def _govern(self) -> None:
        credit = 0.0  # process-ticks beside the test above n so far (below 0: a shortfall to make up)
        recent: list[int] = []
        root, jitter = load_root(), random.Random(os.getpid())
        while True:
            beside, mine = running_beside(os.getpid(), root)
            spinning = len(self.burners.intersection(mine))
            others = len(beside) + len(_ACTIVE.intersection(mine) - self.burners)  # + other blocks here
            self.beside.append(others + spinning)
            self.spinning.append(spinning)
            credit += others + spinning - self.n
            recent = [*recent[-HOLD_TICKS + 1 :], others]
            os.pwrite(self.control, bytes([burners_to_spin(self.n, recent, credit)]), 0)
            if self.done.wait(TICK_S * jitter.uniform(0.8, 1.2)):
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
    """Keep `n` (at most 255) CPU-bound processes beside the block for at most `limit_s` s, burners
    filling in for what else the test run runs (all `n` spin with fill=False); yield the burners."""
    if not 0 <= n <= 255:
        raise ValueError(f"cpu_load: n = {n} burners; 0 to 255")
    with tempfile.TemporaryFile() as control_file:
        control = control_file.fileno()
        os.pwrite(control, bytes([n]), 0)  # every burner spins until the first count
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
            _ACTIVE.difference_update(p.pid for p in procs)
            for proc in procs:
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
            for proc in procs:
                proc.wait()
                if proc.stdout is not None:
                    proc.stdout.close()
            if governor is not None:
                _report(governor, time.monotonic() - started)


def _report(governor: _Governor, seconds: float) -> None:
    """Keep the block's report line (and log it); raise what stopped the governor, if anything did."""
    line = governor.report(seconds)
    LAST_BLOCK[:] = [line]
    if log := os.environ.get("RIG_TEST_LOAD_LOG"):
        with contextlib.suppress(OSError), open(log, "a", encoding="utf-8") as out:
            out.write(line + "\n")
    if governor.failed is not None:
        raise RuntimeError(f"the load governor failed: {governor.failed!r}") from governor.failed


def _stat(pid: int) -> list[str]:
    """A process's /proc stat fields after its name (state first, then the parent's pid, ...): the
    name, in parentheses, may hold spaces and parentheses of its own."""
    with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
        return f.read().rsplit(")", 1)[1].split()


def cpu_seconds(pid: int) -> float:
    """User + system CPU time a running process has used, s (Linux /proc)."""
    fields = _stat(pid)
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
