"""examples/certify_simulated.py runs as written, in its own process, two CPU burners beside it.

What it prints (verdict, mean, expanded uncertainty, run id) must be what the store recorded.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from protocols.procedure import Procedure
from rig.core.bat import BatSpec
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
