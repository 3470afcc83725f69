"""Finding 11 (run part): any error during a run records RunInterrupted and gives the resume command."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.protocols.procedure import Procedure
from rig.protocols.runner import RunControl
from rig.session import sim_config
from rig.store import Store
from tests.protocols.wire import check_fires

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


MISMEASURING_RIG = """
[ports]
cannon = "sim://cannon?scene=ideal"
gates = "sim://gates?scene=ideal"
clamp = "sim://clamp?scene=ideal"
[gates]
positions_m = [4.9, 2.0, 0.5]  # not where the rig's gates are: every speed is measured wrong
"""


def test_cli_mid_run_error_is_an_interruption(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A rig config with the gates in the wrong places sends the aim beyond the calibration mid-run."""
    rig = tmp_path / "rig.toml"
    rig.write_text(MISMEASURING_RIG)
    db = tmp_path / "r.db"
    argv = ["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--config", str(rig)]
    code = main([*argv, "--db", str(db)])
    err = capsys.readouterr().err
    assert code == 3 and "Traceback" not in err and "outside the aim calibration" in err
    run_id = err.split("rig certify --resume ")[1].split()[0]
    assert f"resume with: rig certify --resume {run_id} --config {rig} --db {db}" in err
    with Store.open(db) as store:
        entries = store.entries(run_id)
        assert store.run(run_id).status == "running" and store.verify().ok
    last = entries[-1]
    assert last.kind == "RunInterrupted" and last.payload["reason"] in err
    requested = [e.payload["index"] for e in entries if e.kind == "ShotRequested"]
    resolved = [e.payload["index"] for e in entries if e.kind in ("ShotMeasured", "ShotRejected")]
    assert requested == resolved  # stopped before requesting a shot it could not aim: none lost
    assert main(["runs", "--db", str(db), "--json"]) == 0  # marked interrupted, not left "running"
    (row,) = json.loads(capsys.readouterr().out)
    assert row["run_id"] == run_id and row["status"] == "interrupted" and row["interrupted"] is True
    # the config corrected (here: the simulated rig's own), the run resumes and reaches a verdict
    assert main(["certify", "--resume", run_id, "--sim", "ideal", "--db", str(db)]) in (0, 1)
    with Store.open(db) as store:
        assert store.run(run_id).status == "finished" and store.verify().ok
        assert all(n == 1 for n in check_fires(store.entries(run_id)).values())
    capsys.readouterr()
    assert main(["runs", "--db", str(db), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["interrupted"] is False  # finished now


@pytest.mark.parametrize(
    ("change", "after_fire"),
    [
        ({"cannon_cycle_s": 1e308}, False),  # the lab-time table overflows at the verdict
        ({"timeouts": {"recoil_s": 1e308}}, True),  # waiting for the recoil overflows after FIRE
    ],
)
def test_api_mid_run_error_records_the_interruption_and_resumes(
    tmp_path: Path, change: dict, after_fire: bool
) -> None:
    bat = BatSpec.load(SAMPLE_BAT)
    good = sim_config("ideal", bat=bat)
    # past the files' bounds (which refuse these up front): the generic path must still hold
    update = {
        k: getattr(good, k).model_copy(update=v) if isinstance(v, dict) else v for k, v in change.items()
    }
    if after_fire:  # the ideal scene's clamp reports no recoil: configured with an encoder, it is waited for
        clamp = good.device("clamp").model_copy(update={"options": {"recoil_encoder": True}})
        update["devices"] = good.devices.model_copy(update={"clamp": clamp})
    bad = good.model_copy(update=update)
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, Procedure.load("bbcor"), bat, bad)
        assert out.status == "interrupted" and out.reason
        entries = store.entries(out.run_id)
        assert entries[-1].kind == "RunInterrupted" and entries[-1].payload["reason"] == out.reason
        if after_fire:  # the shot in progress is recorded lost at once, never left pending
            (lost,) = [e.payload for e in entries if e.kind == "ShotLost"]
            assert lost["index"] == 1 and "OverflowError" in lost["reason"]
            assert check_fires(entries) == {1: 1}
        resumed = certify(store, Procedure.load("bbcor"), bat, good, run_id=out.run_id)
        assert resumed.status == "finished" and resumed.verdict.verdict in ("PASS", "FAIL")
        per_shot = check_fires(store.entries(out.run_id))
        assert all(n == 1 for n in per_shot.values())
        assert store.verify().ok


def test_unplugged_device_refuses_a_new_run_and_interrupts_a_resumed_one(tmp_path: Path) -> None:
    """A port that cannot be opened: a new run is refused, nothing recorded (issue 21, item 10); a
    resumed run records why (nothing moved) and resumes once plugged in."""
    bat = BatSpec.load(SAMPLE_BAT)
    good = sim_config("ideal", bat=bat)
    ports = {**good.ports.model_dump(), "gates": str(tmp_path / "no-such-port")}
    unplugged = good.model_copy(update={"ports": type(good.ports).model_validate(ports)})
    with Store.open(tmp_path / "r.db") as store:
        with pytest.raises(ConfigError, match=r"no-such-port.*no run was started"):
            certify(store, Procedure.load("bbcor"), bat, unplugged)
        assert store.runs() == []
        control = RunControl()
        control.abort("stopped before its first step")
        out = certify(store, Procedure.load("bbcor"), bat, good, control=control)
        assert out.status == "interrupted"
        again = certify(store, Procedure.load("bbcor"), bat, unplugged, run_id=out.run_id)
        assert again.status == "interrupted" and "no-such-port" in again.reason
        (last,) = store.entries(out.run_id)[-1:]
        assert last.kind == "RunInterrupted" and last.payload["reason"] == again.reason
        done = certify(store, Procedure.load("bbcor"), bat, good, run_id=out.run_id)
        assert done.status == "finished" and store.verify().ok
        assert all(n == 1 for n in check_fires(store.entries(out.run_id)).values())
