"""Finding 11 (run part): any error during a run records RunInterrupted and gives the resume command."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocols.procedure import Procedure
from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.session import sim_config
from rig.store import Store
from tests.protocols.wire import check_fires

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


def test_cli_mid_run_error_is_an_interruption(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bat file with a 1 Hz hoop frequency breaks the model cross-check at the verdict."""
    bat = tmp_path / "hoop1.toml"
    bat.write_text(SAMPLE_BAT.read_text().replace("hoop_hz = 3600.0", "hoop_hz = 1.0"))
    db = tmp_path / "r.db"
    code = main(["certify", "--procedure", "bbcor", "--bat", str(bat), "--sim", "ideal", "--db", str(db)])
    err = capsys.readouterr().err
    assert code == 3 and "Traceback" not in err
    run_id = err.split("rig certify --resume ")[1].split()[0]
    assert f"resume with: rig certify --resume {run_id} --sim ideal --db {db}" in err
    with Store.open(db) as store:
        last = store.entries(run_id)[-1]
        assert store.run(run_id).status == "running" and store.verify().ok
    assert last.kind == "RunInterrupted" and last.payload["reason"] in err


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
    data = good.model_dump()
    for key, value in change.items():
        data[key] = {**data[key], **value} if isinstance(value, dict) else value
    bad = type(good).model_validate(data)
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
        assert resumed.status == "finished" and resumed.verdict["verdict"] in ("PASS", "FAIL")
        per_shot = check_fires(store.entries(out.run_id))
        assert all(n == 1 for n in per_shot.values())
        assert store.verify().ok


def test_unplugged_device_interrupts_the_new_run_and_it_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A port that cannot be opened: the run records why (nothing moved) and resumes once plugged in."""
    bat = BatSpec.load(SAMPLE_BAT)
    good = sim_config("ideal", bat=bat)
    ports = {**good.ports.model_dump(), "gates": str(tmp_path / "no-such-port")}
    unplugged = good.model_copy(update={"ports": type(good.ports).model_validate(ports)})
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, Procedure.load("bbcor"), bat, unplugged)
        assert out.status == "interrupted" and "no-such-port" in out.reason
        (last,) = store.entries(out.run_id)[-1:]
        assert last.kind == "RunInterrupted" and last.payload["reason"] == out.reason
        assert not store.entries(out.run_id, kinds=["RunStarted", "ShotRequested"])
        done = certify(store, Procedure.load("bbcor"), bat, good, run_id=out.run_id)
        assert done.status == "finished" and store.verify().ok
        assert all(n == 1 for n in check_fires(store.entries(out.run_id)).values())
