"""Machine load beside a test: CPU-bound processes, bounded in time, always cleaned up.

Anything that crosses a process boundary must still pass with two CPU-bound processes running
beside it (a shared lab PC, a CI runner doing other jobs). `cpu_load()` starts them:

    with cpu_load():            # two burners, each gone after at most LIMIT_S
        ...

Each burner spins in pure Python until its deadline, or until its parent is gone (so a test
process killed with SIGKILL does not leave it behind), whichever comes first. Leaving the block,
normally or by an exception, kills and reaps every burner. The pytest fixture `cpu_load` in
tests/conftest.py wraps this for a whole test.

Burners take turns: a block first takes an exclusive lock (flock) on one file in the temporary
folder, shared by every process of the user, so the test workers of a parallel run (pytest-xdist)
do not multiply the load: at most one block's burners run at a time, and the others wait for it.
The kernel releases the lock with the process, so a killed test process never leaves it held.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

BURNERS = 2
LIMIT_S = 300.0  # no test that needs load runs longer; a burner never outlives this

# A busy loop; every ~50 ms it checks the deadline and whether its parent still exists.
_BURN = """
import os, sys, time
deadline, parent = time.monotonic() + float(sys.argv[1]), os.getppid()
print("burning", flush=True)
while time.monotonic() < deadline and os.getppid() == parent:
    n = 0
    for i in range(200_000):
        n += i * i
"""


_held = 0  # how deep this process is inside take_turns() (a block inside a block takes no lock)


def lock_path() -> Path:
    """The file the burners of every test process of this user take turns on."""
    return Path(tempfile.gettempdir()) / f"rig-tests-load-{os.getuid()}.lock"


@contextlib.contextmanager
def take_turns() -> Iterator[None]:
    """Hold the load lock while the block runs (waiting for another process's block to end)."""
    global _held
    if _held:
        _held += 1
        try:
            yield
        finally:
            _held -= 1
        return
    fd = os.open(lock_path(), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        _held = 1
        try:
            yield
        finally:
            _held = 0
    finally:
        os.close(fd)  # releases the lock


@contextlib.contextmanager
def cpu_load(n: int = BURNERS, limit_s: float = LIMIT_S) -> Iterator[list[subprocess.Popen[str]]]:
    """Run `n` CPU-bound processes for at most `limit_s` s while the block runs; yield them.
    Waits first until no other test process runs burners (take_turns)."""
    with take_turns():
        procs: list[subprocess.Popen[str]] = []
        try:
            for _ in range(n):
                procs.append(
                    subprocess.Popen(
                        [sys.executable, "-c", _BURN, repr(limit_s)],
                        stdin=subprocess.DEVNULL,
                        stdout=subprocess.PIPE,
                        stderr=subprocess.DEVNULL,
                        text=True,
                    )
                )
            for proc in procs:  # each one is spinning before the block starts
                assert proc.stdout is not None
                if proc.stdout.readline().strip() != "burning":
                    raise RuntimeError(f"load process {proc.pid} did not start (exit {proc.poll()})")
            yield procs
        finally:
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
