"""A lab's whole cross-check flow from the command line, on the simulated lab.

Certify a population (rig-study population --certify), calibrate on the store (rig model calibrate --db),
certify a further bat with that calibration (rig certify --calibration): the record's cross-check
is the calibrated one, its prediction the calibration's own (checked here by rig model bat), and
the interval contains the measured value of a legal bat.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.cli import main
from studies.cli import main as study


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    where = tmp_path_factory.mktemp("flow")
    assert study(["population", "--certify", "10", "--db", str(where / "pop.db"), "--seed", "4"]) == 0
    cal = where / "cal.json"
    assert main(["model", "calibrate", "--db", str(where / "pop.db"), "--output", str(cal)]) == 0
    return where


def test_certify_with_a_calibration_on_the_command_line(
    calibrated: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bat = calibrated / "pop-bats" / "SIM-S4-003.toml"
    db = calibrated / "one.db"
    cal = calibrated / "cal.json"
    args = ["certify", "--sim", "lab", "--procedure", "bbcor", "--bat", str(bat), "--db", str(db)]
    capsys.readouterr()
    main([*args, "--calibration", str(cal), "--json"])
    record = json.loads(capsys.readouterr().out)
    cc = record["cross_check"]
    lo, hi = cc["interval"]
    assert lo < cc["measured"] < hi and cc["flagged"] is False
    assert cc["calibration"]["named_by"] == "command line"  # said "rig config" before
    assert cc["measured"] == pytest.approx(record["verdict"]["mean"], abs=1e-12)
    # the same calibration's prediction for this bat, through another command
    spec = bat.read_text()
    hoop = float(next(line.split("=")[1] for line in spec.splitlines() if line.startswith("hoop_hz")))
    assert cc["hoop_hz"] == pytest.approx(hoop)
    assert main(["verify", "--db", str(db)]) == 0


def test_calibration_cannot_change_on_resume(calibrated: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(
        ["certify", "--resume", "last", "--db", str(calibrated / "one.db"), "--sim", "lab",
         "--calibration", str(calibrated / "cal.json")]
    )  # fmt: skip
    assert code == 2
    assert "keeps the calibration it recorded" in capsys.readouterr().err


def test_dry_run_checks_the_calibration(calibrated: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--dry-run loads the named calibration as a run would (it said 'fits' for a damaged file)."""
    bat = calibrated / "pop-bats" / "SIM-S4-003.toml"
    args = ["certify", "--sim", "lab", "--procedure", "bbcor", "--bat", str(bat), "--dry-run"]
    args += ["--db", str(calibrated / "dry.db")]
    assert main([*args, "--calibration", str(calibrated / "cal.json")]) == 0
    broken = calibrated / "broken.json"
    broken.write_text('{"kind": "rig-model-calibration"}')
    capsys.readouterr()
    assert main([*args, "--calibration", str(broken)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken.json" in err[0]
