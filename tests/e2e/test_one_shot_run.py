"""`rig shot` fires through the executor as a recorded one-shot run: its intent committed before
FIRE, its raw record, its evaluation; every interlock obeyed; listed by `rig runs` as a shot, never
reported as a certification; checked by `rig verify`."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import pytest

from rig.certification import history
from rig.cli import main
from rig.core.run_state import fold
from rig.report.record import run_record
from rig.simulators.scene import Scene
from rig.simulators.urlhandler import install_world, register, reset_worlds
from rig.store import Store
from rig.tui.report import one_shot_summary


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _kinds(store: Store, run_id: str) -> list[tuple[int, str]]:
    return [(e.seq, e.kind) for e in store.entries(run_id)]


def test_a_shot_is_a_run_with_its_intent_before_fire(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = str(tmp_path / "r.db")
    code, out, _ = cli(
        capsys,
        "shot",
        "--sim",
        "ideal",
        "--speed",
        "60.8",
        "--impact-from-pivot",
        "0.55",
        "--json",
        "--db",
        db,
    )
    assert code == 0
    printed = json.loads(out)
    with Store.open(db, create=False) as store:
        (run,) = store.runs()
        assert (run.run_id, run.procedure, run.status, run.verdict) == (
            printed["run_id"],
            "shot",
            "aborted",  # the store's word for a run ended without a verdict
            None,
        )
        entries = store.entries(run.run_id)
        (requested,) = [e for e in entries if e.kind == "ShotRequested"]
        (fired,) = [e for e in entries if e.kind == "ShotFired"]
        (measured,) = [e for e in entries if e.kind == "ShotMeasured"]
        (located,) = [e for e in entries if e.kind == "LocationSet"]
        assert located.seq < requested.seq < fired.seq < measured.seq  # the intent is committed before FIRE
        # the stage went where it was asked, and the shot was fired there
        assert located.payload["impact_from_pivot_m"] == requested.payload["impact_from_pivot_m"] == 0.55
        assert fired.payload["impact_from_pivot_m"] == printed["impact_from_pivot_m"] == 0.55
        assert fired.payload["crossings"] == printed["crossings"]  # what is printed is what is recorded
        assert (
            measured.payload["inbound_speed_m_s"]
            == printed["inbound_speed_m_s"]
            == pytest.approx(60.8, rel=0.01)
        )
        assert measured.payload["metric"] == pytest.approx(
            printed["rebound_speed_m_s"] / printed["inbound_speed_m_s"]
        )
        assert not [e for e in entries if e.kind == "RunFinished"]  # no verdict: not a certification
        (ended,) = [e for e in entries if e.kind == "RunEnded"]
        assert ended.seq > measured.seq and "no verdict" in ended.payload["why"]
        # the fold of its log and the shown status agree (one run state table)
        assert fold(history(store, run.run_id)).phase == "ended"
        record = run_record(store, run.run_id)
    assert record["verdict"] is None and record["shots"][0]["status"] == "valid"
    summary = one_shot_summary(record)  # the console's history shows it so, not as a certificate
    assert "Not a certification" in summary and "0.55 m from the pivot" in summary
    code, out, _ = cli(capsys, "runs", "--json", "--db", db)
    (row,) = json.loads(out)
    assert (row["procedure"], row["status"], row["verdict"]) == ("shot", "ended", None)
    assert cli(capsys, "verify", "--db", db)[0] == 0
    code, _, err = cli(capsys, "report", "last", "--db", db, "--format", "md")
    assert code == 2 and "is a one-shot run (rig shot), not a certification" in err
    assert "Verdict" not in capsys.readouterr().out
    code, out, _ = cli(capsys, "report", "last", "--db", db, "--format", "json")
    assert code == 0 and json.loads(out)["run_id"] == run.run_id
    code, _, err = cli(capsys, "certify", "--resume", run.run_id, "--sim", "ideal", "--db", db)
    assert code == 2 and "never resumed" in err


def test_an_open_interlock_records_the_intent_and_no_fire(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    register()
    reset_worlds()
    try:
        world = install_world("one-shot-door", "ideal", Scene.load("ideal"))
        world.set_interlock("door", closed=False)
        ports = [
            a
            for d in ("cannon", "gates", "clamp")
            for a in (f"--{d}", f"sim://{d}?scene=ideal&rig=one-shot-door")
        ]
        db = str(tmp_path / "r.db")
        code, _, err = cli(capsys, "shot", "--speed", "60.8", *ports, "--db", db)
        assert code == 2 and "interlock open: door" in err and "\n" not in err.strip()
        assert world.attempts == 0 and not world.shots  # no FIRE reached the cannon
    finally:
        reset_worlds()
    with Store.open(db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "aborted"  # ended with the reason, not left open to resume
        kinds = [k for _, k in _kinds(store, run.run_id)]
        assert "ShotRequested" in kinds and "ShotLost" in kinds and "ShotFired" not in kinds
        assert kinds.index("ShotRequested") < kinds.index("ShotLost") < kinds.index("RunEnded")
        (ended,) = store.entries(run.run_id, kinds=["RunEnded"])
        assert "interlock open: door" in ended.payload["why"]
        sent = b"".join(
            base64.b64decode(c["data_b64"])
            for e in store.entries(run.run_id, kinds=["Traffic"])
            for c in e.payload["chunks"]
            if c["device"] == "cannon" and c["dir"] == "tx"
        )
        assert b"STATUS" in sent and b"FIRE" not in sent
    assert cli(capsys, "verify", "--db", db)[0] == 0


def test_a_shot_the_rig_cannot_give_records_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "r.db"
    code, _, err = cli(capsys, "shot", "--sim", "ideal", "--speed", "150", "--db", str(db))
    assert code == 2 and "dry run" in err and "aim calibration" in err
    assert not db.exists()
