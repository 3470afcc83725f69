"""A stop signal that lands after the run's outcome is recorded (issue 21, item 11).

The outcome is on the record: a device fault's interruption, or the verdict. A SIGINT or SIGTERM
that comes after it, while the process reports it and exits, must not change how the process
ends: exit 3 for the interruption, the verdict's code for a verdict (before, the signal ended the
process: 143 for SIGTERM, 130 or a traceback for SIGINT). Real child processes and real signals.
Each child runs the real `rig` main and then, from an atexit hook (after main has returned and
its signal handling is as it leaves it), says so on stderr and waits for the test: the signal is
sent at that marker, whatever the machine's load (two CPU burners run beside each test), and the
child released after it.

Also: `rig-study population --certify` certifies several bats with one run control; a signal during a later
bat's run was ignored (the first run had settled the control for good).
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from rig.store import Store
from tests.e2e.procs import ROOT, SAMPLE_BAT, wait_count
from tests.unit.clirun import QUICK_PROCEDURE

MARKER = "rig-test: main returned"
CHILD = f"""
import atexit, sys

def hold():
    sys.stderr.write({MARKER!r} + "\\n")
    sys.stderr.flush()
    sys.stdin.readline()  # until the test has sent its signal

atexit.register(hold)
from rig.cli import main
raise SystemExit(main(sys.argv[1:]))
"""


def held_child(*argv: str) -> subprocess.Popen[str]:
    """`rig ARGV` in a child that waits at its exit (after main returned) until stdin gives a line."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT)}
    env.pop("RIG_DB", None)
    return subprocess.Popen(
        [sys.executable, "-c", CHILD, *argv],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def signal_at_exit(child: subprocess.Popen[str], signum: int, timeout_s: float = 300.0) -> str:
    """Wait for the child's exit marker, send `signum`, release it; its whole stderr."""
    lines: queue.Queue[str | None] = queue.Queue()
    assert child.stderr is not None and child.stdin is not None

    def read() -> None:
        assert child.stderr is not None
        for line in child.stderr:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=read, daemon=True).start()
    seen: list[str] = []
    deadline = time.monotonic() + timeout_s
    try:
        while True:
            line = lines.get(timeout=max(0.1, deadline - time.monotonic()))
            assert line is not None, "the child ended without reaching its exit:\n" + "".join(seen)
            seen.append(line)
            if line.strip() == MARKER:
                break
        child.send_signal(signum)
        child.stdin.write("\n")
        child.stdin.close()
        child.wait(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    while (line := lines.get(timeout=10)) is not None:
        seen.append(line)
    return "".join(seen)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_after_a_device_fault_was_recorded_still_exits_3(
    tmp_path: Path, sig: int, cpu_load: None
) -> None:
    db = tmp_path / "r.db"
    child = held_child(
        "certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", "faulty", "--db", str(db)
    )
    err = signal_at_exit(child, sig)
    assert child.returncode == 3, (child.returncode, err[-1500:])
    assert "Traceback" not in err and "rig certify --resume" in err, err[-1500:]
    with Store.open(db) as store:
        (run,) = store.runs()
        assert store.entries(run.run_id)[-1].kind == "RunInterrupted"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_after_the_verdict_still_exits_with_the_verdicts_code(
    tmp_path: Path, sig: int, cpu_load: None
) -> None:
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    db = tmp_path / "r.db"
    argv = ["certify", "--procedure", str(tmp_path / "proc.toml"), "--bat", str(SAMPLE_BAT), "--sim", "ideal"]
    child = held_child(*argv, "--db", str(db))
    err = signal_at_exit(child, sig)
    with Store.open(db) as store:
        (run,) = store.runs()
    assert run.status == "finished"
    assert child.returncode == (0 if run.verdict == "PASS" else 1), (child.returncode, err[-1500:])
    assert "Traceback" not in err, err[-1500:]


def test_study_certify_stops_on_a_signal_during_a_later_bats_run(tmp_path: Path, cpu_load: None) -> None:
    db = tmp_path / "pop.db"
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT)}
    env.pop("RIG_DB", None)
    argv = ["population", "--certify", "2", "--scene", "ideal", "--db", str(db)]
    child = subprocess.Popen(
        [sys.executable, "-m", "studies", *argv],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        wait_count(db, "ShotRequested", 1 + count_first_run_shots(db, child), child)  # the 2nd bat's 1st shot
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=300)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 3, (child.returncode, err[-1500:])
    with Store.open(db) as store:
        runs = store.runs()
        assert [r.status for r in runs] == ["finished", "running"]
        assert "stopped by SIGINT" in store.entries(runs[1].run_id)[-1].payload["reason"]


def count_first_run_shots(db: Path, child: subprocess.Popen[str]) -> int:
    """Wait for the second bat's run to start; the shots the first one requested."""
    wait_count(db, "RunStarted", 2, child)
    with Store.open(db) as store:
        first = store.runs()[0].run_id
        return len(store.entries(first, kinds=["ShotRequested"]))
