"""Helpers for tests that cross a process boundary: CPU burners beside them, a certify child, waits."""

from __future__ import annotations

import contextlib
import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from tests.load import cpu_load

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


@contextlib.contextmanager
def burners(n: int = 2) -> Iterator[None]:
    """`n` CPU-bound processes running beside the test (tests.load: bounded in time, always reaped)."""
    with cpu_load(n):
        yield


def certify_child(db: Path, *args: str) -> subprocess.Popen[str]:
    """`rig certify ... --db DB` in a child process (python -m rig.cli)."""
    return rig_child("certify", *args, "--db", str(db))


def rig_child(*argv: str) -> subprocess.Popen[str]:
    """`rig ARGV...` in a child process (python -m rig.cli), unbuffered, stdout and stderr piped."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "rig.cli", *argv],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


@contextlib.contextmanager
def reaped(proc: subprocess.Popen[str]) -> Iterator[subprocess.Popen[str]]:
    """The child, killed and reaped if the block leaves it running (a failed assert, a timeout)."""
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def count(db: Path, kind: str) -> int:
    """How many entries of `kind` the store holds now (read-only; the child may be writing)."""
    if not db.exists():
        return 0
    try:
        with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5.0)) as conn:
            return conn.execute("SELECT count(*) FROM log WHERE kind = ?", (kind,)).fetchone()[0]
    except sqlite3.OperationalError:  # the child is still creating the store
        return 0


def wait_count(db: Path, kind: str, n: int, proc: subprocess.Popen[str], timeout_s: float = 120.0) -> None:
    """Wait until the store holds `n` entries of `kind` (fail if the child ends first)."""
    deadline = time.monotonic() + timeout_s
    while count(db, kind) < n:
        assert proc.poll() is None, f"the child ended before {n} {kind}: {proc.communicate()}"
        assert time.monotonic() < deadline, f"no {n} {kind} in {timeout_s} s"
        time.sleep(0.005)


def stopped_by_signals(
    proc: subprocess.Popen[str],
    db: Path,
    kind: str,
    n: int,
    signals: tuple[signal.Signals, ...] = (signal.SIGINT,),
    pause_s: float = 0.0,
) -> str:
    """Once the store holds `n` entries of `kind`, send `signals` (each `pause_s` after the last) and
    return the child's stderr; it must end with exit 3 and no traceback (killed if anything fails)."""
    try:
        wait_count(db, kind, n, proc)
        for sig in signals:
            time.sleep(pause_s)
            proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3, err
    assert "Traceback" not in err
    return err
