"""Finding 3: SIGINT and SIGTERM during `rig certify` (a real child process, two CPU burners beside it).

Exit 3, the run recorded as interrupted with the resume command printed, nothing half-written; a
second signal stops at once (the shot it interrupts is recorded lost). Resumed, the run reaches a
verdict with every shot fired once at its recorded location, and `rig verify` passes.
"""

from __future__ import annotations

import signal
from collections import Counter
from pathlib import Path

import pytest

from rig.cli import main
from rig.store import Store
from tests.e2e.procs import SAMPLE_BAT, burners, certify_child, stopped_by_signals
from tests.protocols.wire import check_fires

OUTCOMES = ("ShotMeasured", "ShotRejected", "ShotLost")


@pytest.mark.parametrize(
    ("scene", "kind", "nth", "signals"),
    [
        ("ideal", "MoiMeasured", 1, ("SIGTERM",)),  # right after the pendulum (the chain test: in shots)
        ("faulty", "ShotRequested", 6, ("SIGINT", "SIGINT")),  # the second forces, mid-shot
    ],
)
def test_signal_interrupts_and_the_run_resumes(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    scene: str,
    kind: str,
    nth: int,
    signals: tuple[str, ...],
) -> None:
    db = tmp_path / "r.db"
    with burners():
        child = certify_child(db, "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", scene)
        err = stopped_by_signals(child, db, kind, nth, tuple(getattr(signal, s) for s in signals), 0.1)
    run_id = err.split("rig certify --resume ")[1].split()[0]
    assert f"rig certify --resume {run_id} --sim {scene} --db {db}" in err
    with Store.open(db) as store:
        entries = store.entries(run_id)
        assert store.run(run_id).status == "running" and store.verify().ok
    last = entries[-1]
    assert last.kind == "RunInterrupted"
    assert f"stopped by {signals[0]}" in last.payload["reason"] or "second signal" in last.payload["reason"]
    requested = [e.payload["index"] for e in entries if e.kind == "ShotRequested"]
    outcomes = Counter(e.payload["index"] for e in entries if e.kind in OUTCOMES)
    assert set(outcomes) == set(requested) and all(n == 1 for n in outcomes.values())  # nothing half-written
    if len(signals) == 2:
        assert "second signal" in last.payload["reason"]
        lost = [e.payload for e in entries if e.kind == "ShotLost" and e.payload["index"] == nth]
        # the shot it cut short is lost, not re-fired (if the signals came late, the dropped reply's
        # timeout had already lost it)
        assert lost and ("ForcedStop" in lost[0]["reason"] or "DeviceTimeout" in lost[0]["reason"])
    code = main(["certify", "--resume", run_id, "--sim", "lab", "--db", str(db)])
    assert code in (0, 1)
    capsys.readouterr()
    with Store.open(db) as store:
        after = store.entries(run_id)
        assert store.run(run_id).status == "finished"
    assert after[: len(entries)] == entries
    fired = {e.payload["index"] for e in after if e.kind == "ShotFired"}
    per_shot = check_fires(after)  # every FIRE at its shot's recorded stage position
    assert fired <= set(per_shot) and all(n == 1 for n in per_shot.values())
    assert main(["verify", "--db", str(db)]) == 0
