"""One run interrupted every way a lab meets, then finished on the good rig (issue 9, "done when").

A device fault (the faulty scene), SIGINT, SIGTERM and kill -9 to a `rig certify` child process
(two CPU burners beside it), then the re-shoot budget (a badly scattering cannon) and its recorded
rig check. The run must reach a verdict, every shot fired exactly once (FIRE commands on the
wire, per shot) at its recorded stage position (the MOVE commands on the wire), and `rig verify`
must pass.
"""

from __future__ import annotations

import signal
from collections import Counter
from pathlib import Path

import pytest

from rig.cli import main
from rig.core import events as ev
from rig.store import Store
from tests.e2e.procs import SAMPLE_BAT, burners, certify_child, count, wait_count
from tests.protocols.test_budget import WILD  # a cannon that scatters its speed by 5 %
from tests.protocols.test_run_phase import refusals
from tests.protocols.wire import check_fires


def stop_child(db: Path, run_id: str, how: str, kind: str, more: int) -> None:
    """Resume the run on the lab rig in a child and stop it with `how` after `more` new `kind` entries."""
    with burners():
        child = certify_child(db, "--resume", run_id, "--sim", "lab")
        try:
            wait_count(db, kind, count(db, kind) + more, child)
            child.send_signal(signal.SIGKILL if how == "SIGKILL" else getattr(signal, how))
            _, err = child.communicate(timeout=120)
        finally:
            if child.poll() is None:
                child.kill()
    if how == "SIGKILL":
        assert child.returncode == -9
    else:
        assert child.returncode == 3 and f"rig certify --resume {run_id} --sim lab" in err, err


def test_a_run_interrupted_every_way_resumes_to_a_verdict(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "r.db"
    args = ["--db", str(db)]
    # 1. a device fault: the faulty scene unplugs the gates at its seventh shot
    code = main(["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", "faulty", *args])
    err = capsys.readouterr().err
    assert code == 3
    run_id = err.split("rig certify --resume ")[1].split()[0]
    # 2-4. SIGINT, SIGTERM and kill -9 to a child resuming it on the lab rig
    # (each stopped during a shot, after its intent: a shot's raw record is committed with its outcome)
    stop_child(db, run_id, "SIGINT", "ShotRequested", 2)
    stop_child(db, run_id, "SIGTERM", "ShotRequested", 1)
    stop_child(db, run_id, "SIGKILL", "ShotRequested", 1)
    # 5. the re-shoot budget, on a cannon that scatters its speed by 5 %
    wild = tmp_path / "wild.toml"
    wild.write_text(WILD)
    assert main(["certify", "--resume", run_id, "--sim", str(wild), *args]) == 3
    assert "more than 10 invalid shots" in capsys.readouterr().err
    assert main(["certify", "--resume", run_id, "--sim", "lab", *args]) == 3  # still over budget
    capsys.readouterr()
    # 6. the rig checked (recorded), resumed on the good lab rig to the verdict
    check = ["--rig-checked", "--who", "A. Technician", "--why", "cannon valve replaced"]
    assert main(["certify", "--resume", run_id, "--sim", "lab", *check, *args]) in (0, 1)
    capsys.readouterr()

    with Store.open(db) as store:
        entries = store.entries(run_id)
        assert store.run(run_id).status == "finished"
    kinds = Counter(e.kind for e in entries)
    assert kinds["RunInterrupted"] == 5 and kinds["RunResumed"] == 6 and kinds["RunFinished"] == 1
    reasons = [e.payload["reason"] for e in entries if e.kind == "RunInterrupted"]
    assert "gates" in reasons[0] and "SIGINT" in reasons[1] and "SIGTERM" in reasons[2]
    assert all("invalid shots" in r for r in reasons[3:])  # the kill -9 left no entry of its own
    requested = Counter(e.payload["index"] for e in entries if e.kind == "ShotRequested")
    outcomes = Counter(
        e.payload["index"] for e in entries if e.kind in ("ShotMeasured", "ShotRejected", "ShotLost")
    )
    assert all(n == 1 for n in requested.values()) and outcomes == requested  # one outcome per shot
    fired = {e.payload["index"] for e in entries if e.kind == "ShotFired"}
    per_shot = check_fires(entries)  # each FIRE at its shot's recorded stage position
    assert fired <= set(per_shot) and all(n == 1 for n in per_shot.values())  # none fired twice
    verdict = next(e.payload for e in entries if e.kind == "RunFinished")
    assert verdict["verdict"] in ("PASS", "FAIL") and verdict["n_hits"] == 6
    assert main(["verify", *args]) == 0
    # the kill -9 resumed from a run that was still 'running': the run and shot tables take every entry
    steps = refusals(ev.parse_log(entries))
    assert not [step for step in steps if step[1:] != (None, None)], steps
