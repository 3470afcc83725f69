"""examples/certify_simulated.py runs as written, in its own process, two CPU burners beside it.

What it prints (verdict, mean, expanded uncertainty, run id) must be what the store recorded.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.report.record import run_record
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "certify_simulated.py"


@pytest.mark.slow
def test_the_example_certifies_and_prints_the_recorded_verdict(tmp_path: Path, cpu_load: None) -> None:
    db = tmp_path / "records.db"
    out = subprocess.run(
        [sys.executable, str(EXAMPLE), str(db)], cwd=tmp_path, capture_output=True, text=True, timeout=240
    )
    assert out.returncode in (0, 1), out.stderr
    verdict, mean, big_u, run_id = out.stdout.split()
    with Store.open(db, create=False) as store:
        record = run_record(store, run_id)
        assert [r.run_id for r in store.runs()] == [run_id]
        assert store.verify().ok
    recorded = record["verdict"]
    assert record["status"] == "finished" and verdict == recorded["verdict"]
    assert out.returncode == (0 if verdict == "PASS" else 1)
    assert float(mean) == pytest.approx(recorded["mean"], rel=1e-12)
    assert float(big_u) == pytest.approx(recorded["U"], rel=1e-12)
    assert record["bat"] == BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml").model_dump(
        mode="json"
    )
    assert record["procedure"] == Procedure.load("bbcor").model_dump(mode="json")


@pytest.mark.slow
def test_the_example_writes_to_a_temporary_store_when_given_none(tmp_path: Path, cpu_load: None) -> None:
    out = subprocess.run(
        [sys.executable, str(EXAMPLE)], cwd=tmp_path, capture_output=True, text=True, timeout=240
    )
    assert out.returncode in (0, 1), out.stderr
    assert out.stdout.split()[0] in ("PASS", "FAIL") and list(tmp_path.iterdir()) == []


OWN = ROOT / "examples" / "own_procedure.py"


@pytest.mark.slow
def test_the_own_procedure_example_runs_its_plan_and_the_record_says_so(
    tmp_path: Path, cpu_load: None
) -> None:
    db = tmp_path / "records.db"
    out = subprocess.run(
        [sys.executable, str(OWN), str(db)], cwd=tmp_path, capture_output=True, text=True, timeout=240
    )
    assert out.returncode in (0, 1), out.stderr
    verdict, mean, _, run_id = out.stdout.split()
    with Store.open(db, create=False) as store:
        assert store.verify().ok
        entries = store.entries(run_id)
        record = run_record(store, run_id)
    kinds = [e.kind for e in entries]
    requested = [e.payload for e in entries if e.kind == "ShotRequested"]
    assert requested and {(r["purpose"], r["location_in"]) for r in requested} == {("valid", 6.0)}  # no scan
    at = [i for i, k in enumerate(kinds) if k == "ShotRequested"]
    for prev, i in zip([0, *at], at, strict=False):  # the lab's air is checked before every shot
        assert "EnvironmentChecked" in kinds[prev:i]
    assert record["plan"] == "__main__.screening" and record["verdict"]["verdict"] == verdict
    assert float(mean) == pytest.approx(record["verdict"]["mean"], rel=1e-12)
    fired = [e.payload for e in entries if e.kind == "ShotFired"]
    assert {round(f["impact_from_pivot_m"], 6) for f in fired} == {
        round(BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml").impact_from_pivot_m(6.0), 6)
    }
