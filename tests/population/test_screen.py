"""`rig screen`: the calibrated prediction at a bat's hoop frequency, against an independent solve and a
simulated bat whose truth is known; the hoop frequency's fall; the limit; a screen, never a verdict.

The independent reference: the pivoted bat's collision written here from the model's statement
(rig/physics/bat.py's docstring, founding paper Eqs. 1-2 and 5): ball, hoop mass and the bat body
I/Q^2 - m2 as three masses, the contact force clipped at zero, plain solve_ivp run well past the
contact, e_A the ball's final speed over its inbound speed, BBCOR = e_A (1 + k) + k with k = m Q^2 / I.
The simulated bats come from tests/population/test_crosscheck.py: a population made with the model at
'true' m2 = 0.15 kg, c2 = 400 N s/m plus bat-to-bat scatter of 0.005, calibrated by rig's own fit.
"""

# the fixtures cal, cal_path and record are the cross-check tests', imported: tests take them as arguments
# ruff: noqa: F811

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rig.cli import main
from rig.population.calfile import CalibrationFile
from rig.population.screen import BatModel, bat_model, screen
from tests.modal.test_tap import ping

# the synthetic population, its calibration and the file it is written to, as the cross-check's tests
from tests.population.test_crosscheck import SCATTER, bats, cal, cal_path, record, true_bbcor  # noqa: F401
from tests.unit.clirun import run_cli

BALL_KG = 0.145
SPEED = 60.8
INCH = 0.0254
VERDICT_WORDS = re.compile(r"\b(certified|pass|passed|fail|failed|verdict: )\b", re.IGNORECASE)


def oracle_bbcor(cal: CalibrationFile, model: BatModel, hoop_hz: float) -> float:
    """BBCOR of the model's bat at `hoop_hz` with the calibrated constants, solved here (docstring)."""
    p = cal.model_params
    q = (model.length_in - model.location_in - 6.0) * INCH
    body = model.moi_kgm2 / q**2 - p.m2
    k2 = p.m2 * (2.0 * math.pi * hoop_hz) ** 2

    def rhs(t: float, y: np.ndarray) -> list[float]:
        x1, v1, x2, v2, x3, v3 = y
        d = x1 - x2
        f = max(0.0, p.k1 * d ** (1.0 + p.a) + p.c1 * (v1 - v2) * d**p.b) if d > 0.0 else 0.0
        spring = k2 * (x2 - x3) + p.c2 * (v2 - v3)
        return [v1, -f / p.m1, v2, (f - spring) / p.m2, v3, spring / body]

    sol = solve_ivp(
        rhs, (0.0, 4e-3), [0.0, SPEED, 0.0, 0.0, 0.0, 0.0], "DOP853", rtol=1e-11, atol=1e-13, max_step=1e-6
    )
    assert sol.status == 0
    x1, v1, x2 = sol.y[0], sol.y[1], sol.y[2]
    tail = sol.t > 3e-3
    assert np.ptp(v1[tail]) < 1e-9 * SPEED and np.all(x1[tail] < x2[tail])  # left the barrel for good
    e_a = -float(v1[-1]) / SPEED
    k = BALL_KG * q**2 / model.moi_kgm2
    return e_a * (1.0 + k) + k + cal.parameters.get("offset", 0.0)


@pytest.fixture(scope="module")
def model(cal: CalibrationFile) -> BatModel:
    return bat_model(cal, "B003")


def test_the_calibration_records_each_bats_geometry(record: dict[str, Any]) -> None:
    source = {b.bat_id: b for b in bats(40, seed=11)}
    for row in record["bats"]:
        b = source[row["bat_id"]]
        assert (row["moi_kgm2"], row["length_in"], row["location_in"]) == (
            b.moi_kgm2,
            b.length_in,
            b.location_in,
        )


@pytest.mark.parametrize("hoop", [1500.0, 2100.0, 2900.0])
def test_prediction_is_the_collision_solved_directly(
    cal: CalibrationFile, model: BatModel, hoop: float
) -> None:
    r = screen(cal, model, hoop, 0.5)
    assert r.predicted == pytest.approx(oracle_bbcor(cal, model, hoop), abs=2e-7)


def test_slope_and_the_hoop_frequencys_share_of_u(cal: CalibrationFile, model: BatModel) -> None:
    f, h = 2100.0, 10.0
    slope = (oracle_bbcor(cal, model, f + h) - oracle_bbcor(cal, model, f - h)) / (2 * h)
    r = screen(cal, model, f, 0.5, u_hoop_hz=8.0)
    assert slope < 0.0 and r.slope_per_hz == pytest.approx(slope, rel=2e-3)  # lower hoop, livelier bat
    assert r.u_from_hoop == pytest.approx(8.0 * abs(slope), rel=2e-3)
    plain = screen(cal, model, f, 0.5)
    assert r.u_total**2 == pytest.approx(plain.u_total**2 + r.u_from_hoop**2, rel=1e-12)
    half = r.interval[1] - r.predicted
    assert (
        half == pytest.approx(r.t_factor * r.u_total, rel=1e-12)
        and half > plain.interval[1] - plain.predicted
    )


def test_interval_covers_the_simulated_truth(cal: CalibrationFile, model: BatModel) -> None:
    """Bats of this model broken in to lower hoop frequencies, each with its own scatter: the true
    BBCOR (the model at the true m2, c2, plus a draw of the scatter) lies inside about 95 % of the
    intervals."""
    rng = np.random.default_rng(3)
    inside = []
    for hoop in np.linspace(1500.0, 2900.0, 15):
        r = screen(cal, model, float(hoop), 0.5)
        truth = true_bbcor(float(hoop), model.moi_kgm2, model.length_in, model.location_in)
        assert abs(r.predicted - truth) < 4.0 * r.u_model + 1e-4  # the mean: the true model within u_model
        draws = truth + rng.normal(0.0, SCATTER, 400)
        inside += list((r.interval[0] <= draws) & (draws <= r.interval[1]))
    assert 0.92 <= float(np.mean(inside)) <= 0.98


def test_fall_from_the_models_hoop_frequency(
    cal: CalibrationFile, model: BatModel, record: dict[str, Any]
) -> None:
    f0 = next(b["hoop_hz"] for b in record["bats"] if b["bat_id"] == "B003")
    r = screen(cal, model, 0.9 * f0, 0.5, u_hoop_hz=3.0)
    assert r.model_hoop_hz == f0 and r.model_hoop_source == "calibration file"
    assert r.fall_hz == pytest.approx(0.1 * f0) and r.fall_percent == pytest.approx(10.0)
    given = screen(cal, model, 1800.0, 0.5, model_hoop_hz=2000.0)
    assert (given.fall_hz, given.fall_percent, given.model_hoop_source) == (200.0, 10.0, "given")
    assert given.as_dict()["hoop_fall_u_hz"] == 0.0 and r.as_dict()["hoop_fall_u_hz"] == 3.0


def test_limit_above_below_across(cal: CalibrationFile, model: BatModel) -> None:
    r = screen(cal, model, 2100.0, 0.5)
    lo, hi = r.interval
    cases = {lo - 0.01: ("above", True), hi + 0.01: ("below", False), r.predicted + 1e-4: ("across", False)}
    for limit, (where, exceeds) in cases.items():
        s = screen(cal, model, 2100.0, limit)
        assert (s.interval_vs_limit, s.predicted_exceeds_limit) == (where, exceeds)


def _json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert not VERDICT_WORDS.search(text)
    out: dict[str, Any] = json.loads(text)
    return out


def test_cli_from_the_hoop_frequency(
    cal_path: Path, cal: CalibrationFile, model: BatModel, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["screen", "--hoop-hz", "2000", "--calibration", str(cal_path), "--model-id", "B003"]
    out = _json([*argv, "--json"], capsys)
    assert out["kind"] == "screen" and "screen" in out["statement"]
    assert out["predicted"] == pytest.approx(screen(cal, model, 2000.0, 0.5).predicted, abs=1e-12)
    assert out["limit"] == 0.5 and "bbcor" in out["limit_source"]  # protocols/bbcor.toml's
    assert main(argv) == 0  # the table: a screen, never a verdict, whatever the limit says
    text = capsys.readouterr().out
    assert "SCREEN" in text and "not a certification" in text and not VERDICT_WORDS.search(text)
    for limit in ("0.3", "0.9"):  # above or below: exit 0 both ways
        assert main([*argv, "--limit", limit]) == 0
        assert not VERDICT_WORDS.search(capsys.readouterr().out)


def test_cli_from_a_tap_recording_of_a_simulated_bat(
    tmp_path: Path, cal_path: Path, cal: CalibrationFile, model: BatModel, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bat of model B003 broken in to 1900 Hz, tapped: the screen finds its hoop frequency within
    1 %, and its interval covers the simulated bat's true BBCOR (the true model at 1900 Hz)."""
    from scipy.io import wavfile

    wav = tmp_path / "tap.wav"
    wavfile.write(wav, 48000, np.round(ping(1900.0) * 32767).astype(np.int16))
    argv = ["screen", "--recording", str(wav), "--calibration", str(cal_path), "--model-id", "B003"]
    out = _json([*argv, "--json", "--certified-hoop-hz", "2300"], capsys)
    assert abs(out["hoop_hz"] - 1900.0) < 19.0 and out["hoop_u_hz"] > 0.0
    assert out["tap"]["hoop_hz"] == out["hoop_hz"] and out["model_hoop_hz"] == 2300.0
    assert out["hoop_fall_hz"] == pytest.approx(2300.0 - out["hoop_hz"])
    truth = true_bbcor(1900.0, model.moi_kgm2, model.length_in, model.location_in)
    assert out["interval"][0] <= truth <= out["interval"][1]
    given = screen(cal, model, out["hoop_hz"], 0.5)
    assert out["predicted"] == pytest.approx(given.predicted, abs=1e-12)
    assert out["u_from_hoop"] == pytest.approx(abs(given.slope_per_hz) * out["hoop_u_hz"], rel=1e-6)


def _one_line(argv: list[str], cause: str) -> None:
    res = run_cli(argv)
    assert res.code == 2, res.err
    assert len(res.err.strip().splitlines()) == 1 and cause in res.err, res.err


def test_hostile_and_bad_inputs_are_one_line(tmp_path: Path, cal_path: Path, record: dict[str, Any]) -> None:
    base = ["screen", "--hoop-hz", "2000", "--calibration", str(cal_path)]
    _one_line(base, "--model-id ID is needed")
    _one_line(["screen", "--calibration", str(cal_path), "--model-id", "B003"], "--hoop-hz F or --recording")
    _one_line([*base, "--model-id", "B003", "--recording", "x.wav"], "one of them")
    _one_line([*base, "--model-id", "NOPE"], "no bat model 'NOPE'")
    _one_line(
        ["screen", "--hoop-hz", "99", "--calibration", str(cal_path), "--model-id", "B003"], "--hoop-hz"
    )
    _one_line([*base, "--model-id", "B003", "--limit", "1.5"], "--limit 1.5 is outside")
    garbage = tmp_path / "garbage.json"
    garbage.write_bytes(b"\x00\xff{not json")
    _one_line(
        ["screen", "--hoop-hz", "2000", "--calibration", str(garbage), "--model-id", "B003"], "garbage.json"
    )
    wrong = tmp_path / "wrong.json"
    wrong.write_text(json.dumps({**record, "kind": "a ball"}), encoding="utf-8")
    _one_line(["screen", "--hoop-hz", "2000", "--calibration", str(wrong), "--model-id", "B003"], "kind")
    old = tmp_path / "old.json"  # a calibration written before the bats' geometry was recorded
    rows = [
        {k: v for k, v in b.items() if k not in ("moi_kgm2", "length_in", "location_in")}
        for b in record["bats"]
    ]
    old.write_text(json.dumps({**record, "bats": rows}), encoding="utf-8")
    _one_line(
        ["screen", "--hoop-hz", "2000", "--calibration", str(old), "--model-id", "B003"], "calibrate again"
    )
    bad_wav = tmp_path / "bad.wav"
    bad_wav.write_bytes(b"RIFF\x10\x00\x00\x00WAVEjunk")
    rec = ["screen", "--recording", str(bad_wav), "--calibration", str(cal_path), "--model-id", "B003"]
    _one_line(rec, "bad.wav")
    _one_line([*rec[:2], str(tmp_path / "absent.wav"), *rec[3:]], "absent.wav")


@pytest.mark.parametrize("flag", ["--hoop-hz", "--certified-hoop-hz", "--limit", "--coverage"])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "0", "-1", "1e300", "5e-324", "yes", "0x10", ""])
def test_extreme_flag_values_are_one_line(cal_path: Path, flag: str, value: str) -> None:
    argv = ["screen", "--hoop-hz", "2000", "--calibration", str(cal_path), "--model-id", "B003"]
    argv = [a for a in argv if a != "--hoop-hz" and a != "2000"] if flag == "--hoop-hz" else argv
    res = run_cli([*argv, f"{flag}={value}"])  # "--flag -1" would read -1 as a flag
    if (flag, value) == ("--limit", "5e-324"):  # inside BBCOR's (0, 1]: a screen, exit 0
        assert res.code == 0, res.err
        return
    assert res.code == 2 and res.err.strip(), (flag, value)
    assert "Traceback" not in res.err
    if value not in ("yes", "0x10", ""):  # argparse's own type error prints its usage line too
        assert len(res.err.strip().splitlines()) == 1, res.err
