"""Finding 1: every shot fires with the stage at its recorded location, whatever came before.

Checked from the wire (the recorded device traffic), not from the runner's own bookkeeping.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.store import Store
from tests.protocols.wire import check_fires, expected_stage_mm, wire_fires

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


def test_resume_after_a_fault_in_the_scan_fires_at_the_recorded_location(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "r.db"
    args = ["--db", str(db)]
    code = main(["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", "faulty", *args])
    assert code == 3  # the faulty scene unplugs the gates during the scan
    run_id = capsys.readouterr().err.split("rig certify --resume ")[1].split()[0]
    with Store.open(db) as store:
        before = store.entries(run_id)
    resumed_at = [e.payload["location_in"] for e in before if e.kind == "ShotRequested"]
    assert resumed_at[-1] > 5.0  # interrupted past the scan's first location
    assert main(["certify", "--resume", run_id, "--sim", "lab", *args]) in (0, 1)
    with Store.open(db) as store:
        entries = store.entries(run_id)
    per_shot = check_fires(entries)
    fired = {e.payload["index"] for e in entries if e.kind == "ShotFired"}
    assert fired <= set(per_shot) and all(n == 1 for n in per_shot.values())  # no shot fired twice


def test_wire_check_sees_a_wrong_stage_position(tmp_path: Path) -> None:
    """The check itself can fail: a record whose location disagrees with the MOVE is caught."""
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, Procedure.load("bbcor"), bat, sim_config("ideal", bat=bat))
        entries = store.entries(out.run_id)
    fires = wire_fires(entries)
    assert fires and all(f.stage_mm is not None for f in fires)
    assert fires[0].stage_mm == pytest.approx(expected_stage_mm({"length_in": 33.0}, 5.0))  # 558.8 mm
    assert fires[0].stage_mm == pytest.approx(558.8)
    forged = [
        replace(e, payload={**e.payload, "location_in": 6.0})
        if e.kind == "ShotRequested" and e.payload["index"] == 1
        else e
        for e in entries
    ]
    with pytest.raises(AssertionError, match=r"shot 1 recorded at 6\.0 in"):
        check_fires(forged)
