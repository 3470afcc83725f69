"""The store deleted or truncated under a running `rig certify` (issue 21, item 1), across the process
boundary: the child notices at its next write, stops with exit 2 and one line, and prints no verdict.

The child is paused (SIGSTOP) once it has fired a few shots and is known not to have finished, the
files are deleted or cut, and it is let go (SIGCONT): no sleeps, nothing left to timing, two CPU
burners beside it.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from tests.e2e.procs import SAMPLE_BAT, burners, certify_child, count, wait_count


def _delete(db: Path) -> None:
    for suffix in ("", "-wal", "-shm"):
        db.with_name(db.name + suffix).unlink(missing_ok=True)


def _truncate(db: Path) -> None:
    os.truncate(db, 0)


@pytest.mark.parametrize("harm", [_delete, _truncate], ids=["deleted", "truncated"])
def test_a_store_harmed_during_a_run_stops_it_with_no_verdict(tmp_path: Path, harm: object) -> None:
    db = tmp_path / "d.db"
    with burners():
        child = certify_child(db, "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", "lab")
        try:
            wait_count(db, "ShotFired", 3, child)
            child.send_signal(signal.SIGSTOP)
            assert count(db, "RunFinished") == 0  # paused mid-run, well before its verdict
            if harm is _truncate:  # the log in the file itself, not only in the WAL
                assert db.stat().st_size > 0
            harm(db)  # type: ignore[operator]
            child.send_signal(signal.SIGCONT)
            out, err = child.communicate(timeout=300)
        finally:
            if child.poll() is None:
                child.kill()
                child.communicate()
    assert child.returncode == 2, (out, err)
    last = err.strip().splitlines()[-1]
    assert last.startswith("rig: ") and "d.db" in last and "stopped without a verdict" in last, err
    assert err.count("rig: ") == 1 and "Traceback" not in err
    assert "PASS" not in out + err and "FAIL" not in out + err  # no verdict the store does not hold
