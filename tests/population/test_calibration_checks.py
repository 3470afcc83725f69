"""A calibration file is checked as strictly as a bat file (issue 21, item 9).

Physical ranges for the parameters and the ball, finite numbers, a symmetric positive
semi-definite covariance that agrees with the stated uncertainties, a scatter that is a standard
deviation, model constants that are the parameters' own, and a provenance with degrees of
freedom. Before: m2 < 0 crashed `rig model crosscheck` (math domain error) and put "domain error"
on a certificate that exited 0; a negative scatter or a covariance that is not positive
semi-definite was accepted.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import pytest

from rig.cli import main
from rig.core.errors import ConfigError
from rig.population import load_population
from rig.population.calfile import calibration_record, load_calibration, write_calibration
from rig.population.calibrate import calibrate
from rig.store import Store
from tests.unit.clirun import GOOD_BAT, ROOT

POPULATION = ROOT / "protocols" / "examples" / "population.csv"


@pytest.fixture(scope="module")
def record() -> dict[str, Any]:
    """A good m2+c2 calibration of the example population."""
    return calibration_record(calibrate(load_population(POPULATION), variants=("m2+c2",)), b"x", "pop.csv")


def _set(record: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    out = copy.deepcopy(record)
    *head, last = path.split(".")
    where = out
    for key in head:
        where = where[int(key)] if isinstance(where, list) else where[key]
    if isinstance(where, list):
        where[int(last)] = value
    else:
        where[last] = value
    return out


def _not_psd(record: dict[str, Any]) -> dict[str, Any]:
    """Correlation 3 between m2 and c2 (the diagonal, and so the uncertainties, kept)."""
    out = copy.deepcopy(record)
    c = out["covariance"]
    c[0][1] = c[1][0] = 3.0 * math.sqrt(c[0][0] * c[1][1])
    return out


def _asymmetric(record: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(record)
    out["covariance"][0][1] = -out["covariance"][0][1]
    return out


CASES: list[tuple[str, Any, str]] = [
    ("parameters.m2", -0.05, "parameters.m2"),
    ("parameters.m2", 5.0, "parameters.m2"),
    ("parameters.c2", -10.0, "parameters.c2"),
    ("uncertainty.m2", -0.001, "uncertainty.m2"),
    ("uncertainty.m2", 0.5, "uncertainty.m2"),  # not the covariance's sqrt(C[0][0])
    ("scatter", -0.005, "scatter"),
    ("scatter", 50.0, "scatter"),  # wider than the whole BBCOR scale
    ("loo_rmse", -0.005, "loo_rmse"),
    ("speed_m_s", -60.8, "speed_m_s"),
    ("default_location_in", -6.5, "default_location_in"),
    ("model_params.m2", 0.5, "model_params"),  # not the parameters' m2
    ("model_params.a", 7.0, "model_params"),
    ("provenance.n_bats", 2, "provenance.n_bats"),
    ("provenance.hoop_min_hz", -5.0, "provenance.hoop"),
    ("provenance.hoop_max_hz", 1000.0, "provenance.hoop"),  # below hoop_min_hz
    ("ball", {}, "ball"),
    ("ball", {"constants": {"m1": 0.145, "z": 1.0}}, "ball"),
]


@pytest.mark.parametrize(("path", "value", "field"), CASES, ids=[f"{p}={v}" for p, v, _ in CASES])
def test_a_value_out_of_its_range_is_refused_naming_the_field(
    record: dict[str, Any], tmp_path: Path, path: str, value: Any, field: str
) -> None:
    bad = tmp_path / "cal.json"
    bad.write_text(json.dumps(_set(record, path, value)), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_calibration(bad)
    message = str(info.value)
    assert message.startswith(str(bad)) and field in message and "\n" not in message, message


@pytest.mark.parametrize("damage", [_not_psd, _asymmetric], ids=["not PSD", "asymmetric"])
def test_a_covariance_that_is_no_covariance_is_refused(
    record: dict[str, Any], tmp_path: Path, damage: Any
) -> None:
    bad = tmp_path / "cal.json"
    bad.write_text(json.dumps(damage(record)), encoding="utf-8")
    with pytest.raises(ConfigError, match="covariance"):
        load_calibration(bad)


def test_non_finite_numbers_are_refused(record: dict[str, Any], tmp_path: Path) -> None:
    for path in ("covariance.0.0", "scatter", "parameters.c2"):
        bad = tmp_path / "cal.json"
        bad.write_text(json.dumps(_set(record, path, float("nan"))), encoding="utf-8")  # NaN: JSON allows it
        with pytest.raises(ConfigError, match="finite"):
            load_calibration(bad)


def test_the_good_file_still_loads_and_round_trips(record: dict[str, Any], tmp_path: Path) -> None:
    path = write_calibration(record, tmp_path / "cal.json")
    assert load_calibration(path).parameters == record["parameters"]


def test_crosscheck_refuses_a_negative_m2_in_one_line(
    record: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "cal.json"
    bad.write_text(json.dumps(_set(record, "parameters.m2", -0.05)), encoding="utf-8")
    code = main(["model", "crosscheck", "--data", str(POPULATION), "--calibration", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and str(bad) in err and "parameters.m2" in err, err


@pytest.mark.parametrize(
    ("path", "value"), [("parameters.m2", -0.05), ("scatter", -0.005)], ids=["m2 < 0", "scatter < 0"]
)
def test_certify_refuses_a_bad_calibration_before_the_run(
    record: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str], path: str, value: float
) -> None:
    bad = tmp_path / "cal.json"
    bad.write_text(json.dumps(_set(record, path, value)), encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    db = tmp_path / "r.db"
    argv = ["certify", "--procedure", "bbcor", "--bat", str(tmp_path / "bat.toml"), "--sim", "ideal"]
    code = main([*argv, "--db", str(db), "--calibration", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and str(bad) in err and path in err, err
    with Store.open(db) as store:
        assert store.runs() == []
