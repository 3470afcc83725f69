"""Finding 5: air drag biased BBCOR low; corrected to the impact point, drag and ideal scenes agree."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocols.procedure import Procedure
from rig.certification import certify
from rig.core.bat import BatSpec
from rig.session import sim_config
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


def _mean(tmp_path: Path, scene: str) -> dict:
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(tmp_path / f"{scene}.db") as store:
        out = certify(store, Procedure.load("bbcor"), bat, sim_config(scene, bat=bat))
    return out.verdict


@pytest.fixture(scope="module")
def verdicts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict]:
    tmp = tmp_path_factory.mktemp("dragscene")
    return {scene: _mean(tmp, scene) for scene in ("ideal", "drag")}


def test_drag_only_scene_agrees_with_ideal_scene(verdicts: dict[str, dict]) -> None:
    ideal, drag = verdicts["ideal"]["mean"], verdicts["drag"]["mean"]
    assert abs(drag - ideal) <= 0.0003, f"drag scene {drag:.5f} vs ideal {ideal:.5f}"


def test_drag_correction_is_in_the_budget(verdicts: dict[str, dict]) -> None:
    inputs = verdicts["drag"]["budget"]["inputs"]
    for name in ("Cd_in", "Cd_out", "rho"):
        assert inputs[name]["systematic"] and inputs[name]["u"] > 0.0
    shares = verdicts["drag"]["budget"]["outputs"]["bbcor"]["contributions"]
    assert shares["Cd_in"] > 0.0 and shares["rho"] > 0.0


def test_without_the_correction_the_drag_scene_reads_low(verdicts: dict[str, dict]) -> None:
    drag = verdicts["drag"]["drag"]
    assert drag["applied"] and not verdicts["ideal"]["drag"]["applied"]
    assert verdicts["ideal"]["mean"] - drag["mean_uncorrected"] > 0.0009  # the bias found (0.0012)
    assert drag["correction"] == pytest.approx(verdicts["drag"]["mean"] - drag["mean_uncorrected"])


def test_guarded_decision_uses_the_corrected_mean_and_whole_budget(verdicts: dict[str, dict]) -> None:
    v = verdicts["drag"]
    assert v["mean"] == pytest.approx(sum(v["hits"]) / len(v["hits"]))
    assert v["mean"] > v["drag"]["mean_uncorrected"]
    out = v["budget"]["outputs"]["bbcor"]
    # the decision's u holds every systematic input (I, Q, gates, ball, Cd, rho) at least
    assert v["u"] ** 2 >= out["systematic_variance"] * (1 - 1e-12)
    assert (v["verdict"] == "PASS") == (v["mean"] + v["U"] <= v["limit"])
