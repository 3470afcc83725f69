"""`rig-study population --calibration CAL.json`: the calibrated model's curve beside the paper's
(issue 10, 2)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.physics import DEFAULT_PARAMS, PivotedBat, predict_bat
from rig.population import write_population_csv
from rig.population.calfile import CalibrationFile, calibration_record, load_calibration, write_calibration
from rig.population.calibrate import calibrate, fit_bats, predict
from rig.population.dataset import PopulationBat
from studies.cli import main
from studies.population.study import run_study
from tests.population.test_calibrate import population

INCH = 0.0254


@pytest.fixture(scope="module")
def cal_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two calibrations: m2+c2 on plain data, and the offset variant on data 0.03 BBCOR above the model."""
    out = {}
    tmp = tmp_path_factory.mktemp("cal")
    for name, offset, variant in (("plain", 0.0, "m2+c2"), ("offset", 0.03, "m2+c2+offset")):
        bats = population(n=14, seed=5, offset=offset)
        data = write_population_csv(bats, tmp / f"{name}.csv")
        record = calibration_record(calibrate(bats, "bbcor", (variant,)), data.read_bytes(), str(data))
        out[name], out[f"{name}-data"] = write_calibration(record, tmp / f"{name}.json"), data
    return out


def reference(hoop: float, location_in: float | None = 6.8) -> PopulationBat:
    return PopulationBat(
        bat_id="REF",
        barrel="aluminium",
        hoop_hz=hoop,
        length_in=32.0,
        moi_kgm2=0.178,
        location_in=location_in,
        bbcor=0.47,
    )


def by_hoop(curve: dict, metric: str) -> dict[float, float]:
    return dict(zip(curve["hoop_hz"], curve[metric], strict=True))


@pytest.mark.parametrize("name", ["plain", "offset"])
def test_the_calibrated_curve_is_the_calibrations_own_prediction_for_the_bat(
    cal_files: dict[str, Path], name: str
) -> None:
    cal = load_calibration(cal_files[name])
    assert ("offset" in cal.parameters) == (name == "offset")
    assert cal.parameters.get("offset", 0.03) != 0.0
    for location in (6.8, None):  # its own location, or the calibration's default
        # three bats of the same length, MOI and location: the grid spans 1500-2400 Hz
        bats = [reference(h, location) for h in (1500.0, 2000.0, 2400.0)]
        study = run_study(bats, calibration=cal)
        assert study.calibrated is not None
        curve = by_hoop(study.calibrated, "bbcor")
        for hoop in (1500.0, 2000.0, 2400.0):
            own = float(predict(fit_bats([reference(hoop, location)], "bbcor"), cal.parameters)[0])
            assert curve[hoop] == pytest.approx(own, abs=1e-6)
            # and written out: predict_bat at the calibrated constants, Eq. 5, the offset
            loc = cal.default_location_in if location is None else location
            q = (32.0 - loc - 6.0) * INCH
            params = DEFAULT_PARAMS.model_copy(
                update={
                    "m1": 0.145,
                    "m2": cal.parameters["m2"],
                    "c2": cal.parameters["c2"],
                    "k1": DEFAULT_PARAMS.k1 * cal.parameters.get("k1_scale", 1.0),
                }
            )
            e_a = predict_bat(params, 60.8, hoop, PivotedBat(moi_kgm2=0.178, impact_from_pivot_m=q)).e_a
            k = 0.145 * q * q / 0.178
            assert curve[hoop] == pytest.approx(
                e_a * (1 + k) + k + cal.parameters.get("offset", 0.0), abs=1e-6
            )
        # the paper's curve is still there, unchanged, and another curve
        paper = by_hoop(run_study(bats).model, "bbcor")
        assert by_hoop(study.model, "bbcor") == paper
        assert abs(paper[2000.0] - curve[2000.0]) > 0.01


def _cal(path: Path) -> CalibrationFile:
    return load_calibration(path)


def test_cli_json_and_figure_carry_the_calibrated_model(
    cal_files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data, cal = cal_files["offset-data"], cal_files["offset"]
    args = ["population", "--data", str(data), "--calibration", str(cal), "--json"]
    args += ["--plot-dir", str(tmp_path)]
    assert main(args) == 0
    out = json.loads(capsys.readouterr().out)
    model = out["calibrated_model"]
    loaded = _cal(cal)
    assert model["variant"] == loaded.variant and model["parameters"] == loaded.parameters
    assert model["file"] == str(cal) and model["provenance"]["n_bats"] == 14
    assert model["hoop_hz"] == out["model"]["hoop_hz"] and len(model["bbcor"]) == len(model["hoop_hz"])
    # the offset data sit 0.03 above the paper-constant model: the calibrated curve follows the bats
    measured = [b["mean"] for b in out["fig6"]["metrics"]["bbcor"]]
    assert abs(sum(model["bbcor"]) / len(model["bbcor"]) - sum(measured) / len(measured)) < 0.02
    assert "calibrated_slope_per_khz" in out["trend"]["bbcor"]
    assert (tmp_path / "fig6-metrics-vs-hoop.png").read_bytes().startswith(b"\x89PNG")
    svg = (tmp_path / "fig6-metrics-vs-hoop.svg").read_text()
    assert "calibrated model" in svg and "paper" in svg
    # without --calibration nothing changes
    assert main(["population", "--data", str(data), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["calibrated_model"] is None


def test_a_bad_calibration_file_is_refused_with_one_line(
    cal_files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert main(["population", "--data", str(cal_files["plain-data"]), "--calibration", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "Traceback" not in err
