"""Finding 2: a run over its re-shoot budget has a recorded way out (rig checked, or ended)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.cli import main
from rig.store import Store
from tests.protocols.wire import check_fires

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
# A rig whose cannon scatters its speed by 5 %: most shots miss the 1 mph tolerance (invalid).
WILD = """
description = "badly scattering cannon"
seed = 3
[[effects]]
kind = "speed_scatter"
sigma_rel = 0.05
"""


def over_budget(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[list[str], str, str]:
    """A run stopped by the re-shoot budget; returns the --db args, its id and the message."""
    scene = tmp_path / "wild.toml"
    scene.write_text(WILD)
    db = ["--db", str(tmp_path / "r.db")]
    code = main(["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", str(scene), *db])
    err = capsys.readouterr().err
    assert code == 3 and "more than 10 invalid shots" in err
    return db, err.split("rig certify --resume ")[1].split()[0], err


def test_rig_check_restarts_the_budget(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    db, run_id, err = over_budget(tmp_path, capsys)
    assert "--rig-checked --who NAME --why TEXT" in err and f"rig certify --end {run_id}" in err
    with Store.open(db[1]) as store:
        n_before = len(store.entries(run_id, kinds=["ShotRequested"]))
    assert main(["report", run_id, "--format", "md", *db]) == 0
    md = capsys.readouterr().out  # the certificate of the stopped run shows both ways out
    assert f"--resume {run_id} --sim {tmp_path / 'wild.toml'} --rig-checked --who NAME" in md
    assert f"rig certify --end {run_id} --who NAME --why TEXT" in md
    # resuming on a good rig without the recorded check stops at once, before any shot
    assert main(["certify", "--resume", run_id, "--sim", "ideal", *db]) == 3
    assert "more than 10 invalid shots in this run" in capsys.readouterr().err
    with Store.open(db[1]) as store:
        assert len(store.entries(run_id, kinds=["ShotRequested"])) == n_before
    assert main(["certify", "--resume", run_id, "--sim", "ideal", "--rig-checked", *db]) == 2
    assert "--who NAME and --why TEXT" in capsys.readouterr().err
    who, why = "A. Technician", "cannon seal replaced; speed scatter back to 0.2 %"
    code = main(
        ["certify", "--resume", run_id, "--sim", "ideal", "--rig-checked", "--who", who, "--why", why, *db]
    )
    assert code in (0, 1)
    capsys.readouterr()
    with Store.open(db[1]) as store:
        entries = store.entries(run_id)
        assert store.verify().ok and store.run(run_id).status == "finished"
    (check,) = [e.payload for e in entries if e.kind == "RigChecked"]
    at = next(i for i, e in enumerate(entries) if e.kind == "RigChecked")
    invalid = [e for e in entries[:at] if e.kind in ("ShotRejected", "ShotLost")]
    assert check["who"] == who and check["why"] == why and check["invalid_shots_before"] == len(invalid) == 11
    per_shot = check_fires(entries)
    assert all(n == 1 for n in per_shot.values())
    assert main(["report", run_id, "--format", "json", *db]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["rig_checks"][0]["who"] == who and rec["verdict"]["n_hits"] == 6
    assert main(["report", run_id, "--format", "md", *db]) == 0
    md = capsys.readouterr().out
    assert "| rig checked |" in md and who in md and why in md
    assert main(["certify", "--end", run_id, "--who", who, "--why", "too late", *db]) == 2
    assert "already finished" in capsys.readouterr().err  # a finished run stays as it is


def test_end_a_run_without_a_verdict(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    db, run_id, _ = over_budget(tmp_path, capsys)
    assert main(["certify", "--end", run_id, "--who", "Q. Manager", *db]) == 2  # no reason given
    capsys.readouterr()
    assert (
        main(["certify", "--end", run_id, "--who", "Q. Manager", "--why", "cannon sent for repair", *db]) == 0
    )
    capsys.readouterr()
    with Store.open(db[1]) as store:
        assert store.run(run_id).status == "aborted" and store.verify().ok
    assert main(["certify", "--resume", run_id, "--sim", "ideal", *db]) == 2  # ended runs stay ended
    assert "ended without a verdict" in capsys.readouterr().err
    assert main(["report", run_id, "--format", "json", *db]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["status"] == "ended" and rec["verdict"] is None  # stored 'aborted', shown 'ended' everywhere
    assert rec["ended"]["who"] == "Q. Manager" and rec["ended"]["why"] == "cannon sent for repair"
    for fmt in ("md", "html"):
        assert main(["report", run_id, "--format", fmt, *db]) == 0
        text = capsys.readouterr().out
        assert "Run ended without a verdict by Q. Manager" in text and "cannon sent for repair" in text
        assert "--resume" not in text  # nothing to resume


def test_a_run_is_not_ended_while_a_runner_holds_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db, run_id, _ = over_budget(tmp_path, capsys)
    with Store.open(db[1]) as runner_store, runner_store.run_lock(run_id):  # a live runner (this pid)
        assert main(["certify", "--end", run_id, "--who", "Q. Manager", "--why", "repair", *db]) == 2
        assert "already being run" in capsys.readouterr().err
    with Store.open(db[1]) as store:
        assert store.run(run_id).status == "running" and not store.entries(run_id, kinds=["RunEnded"])
