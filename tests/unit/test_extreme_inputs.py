"""Extreme values in files and flags: one line naming the cause, exit 2, no run left behind.

Each case was found by trying the controller as a user would; before the bounds, each ended in a
traceback, a run left 'running' after FIRE, or minutes of computation.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE, ROOT, run_cli

EXAMPLE_RIG = (ROOT / "protocols" / "examples" / "rig.toml").read_text()
SIM_PORTS = {
    '"/dev/ttyUSB0"': '"sim://cannon?scene=ideal"',
    '"/dev/ttyUSB1"': '"sim://gates?scene=ideal"',
    '"/dev/ttyUSB2"': '"sim://clamp?scene=ideal"',
}


def sim_rig(old: str = "", new: str = "") -> str:
    """The example rig config on the simulated ideal rig, with one line replaced."""
    text = EXAMPLE_RIG
    for a, b in SIM_PORTS.items():
        text = text.replace(a, b)
    assert old in text
    return text.replace(old, new)


def certify(tmp_path: Path, bat: str = GOOD_BAT, procedure: str = QUICK_PROCEDURE, **where: str) -> object:
    (tmp_path / "bat.toml").write_text(bat)
    (tmp_path / "proc.toml").write_text(procedure)
    db = tmp_path / "r.db"
    argv = ["certify", "--procedure", str(tmp_path / "proc.toml"), "--bat", str(tmp_path / "bat.toml")]
    if "config" in where:
        (tmp_path / "rig.toml").write_text(where["config"])
        argv += ["--config", str(tmp_path / "rig.toml")]
    elif "scene" in where:
        (tmp_path / "scene.toml").write_text(where["scene"])
        argv += ["--sim", str(tmp_path / "scene.toml")]
    else:
        argv += ["--sim", "ideal"]
    return run_cli([*argv, "--db", str(db)], db)


def refused(result: object, *needles: str) -> None:
    """Exit 2, one line on stderr naming every needle, no traceback, no run left running."""
    assert result.code == 2, result.err
    lines = result.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.err, result.err
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert result.stray_runs == []


@pytest.mark.parametrize(
    ("line", "needle"),
    [
        ("balance_point_in = 39.0", "balance_point_in"),  # beyond the 33 in bat's tip
        ("balance_point_in = 4.0", "balance_point_in"),  # between the knob and the pivot
        ("moi_kgm2 = 1e-9", "moi_kgm2"),
        ("moi_kgm2 = 0.05", "m d^2"),  # below the parallel-axis minimum for this balance point
        ("hoop_hz = 1e300", "hoop_hz"),
        ("hoop_hz = 1.0", "hoop_hz"),  # the barrel swallowed the ball (v_out < 0) mid-run
        ("length_in = 1e300", "length_in"),
    ],
)
def test_bat_file_out_of_bounds(tmp_path: Path, line: str, needle: str) -> None:
    key = line.split(" = ")[0]
    kept = "".join(f"{x}\n" for x in GOOD_BAT.splitlines() if not x.startswith(key))
    refused(certify(tmp_path, bat=kept + line + "\n"), needle)


def test_bat_without_balance_point_the_simulated_rig_cannot_hold(tmp_path: Path) -> None:
    # MOI 0.05 kg m^2 is a real (youth) bat's, but not with the simulated bat's balance point:
    # the scene says so in one line instead of a pydantic traceback
    bat = GOOD_BAT.replace("balance_point_in = 22.0\n", "moi_kgm2 = 0.05\n")
    refused(certify(tmp_path, bat=bat), "simulated rig", "m d^2")


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("positions_m = [0.75, 0.50, 0.25]", "positions_m = [3e8, 2e8, 1e8]", "positions_m"),
        ("positions_m = [0.75, 0.50, 0.25]", "positions_m = [0.75, 0.74, 0.25]", "20 mm"),
        ("positions_m = [0.75, 0.50, 0.25]", "positions_m = [0.75, 0.50, 0.0]", "bat's way"),
        ("reply_s = 1.0", "reply_s = 1e308", "reply_s"),
        ("reply_s = 1.0", "reply_s = 1e-300", "reply_s"),
        ("shot_window_s = 0.5", "shot_window_s = 1e308", "shot_window_s"),
        ("shot_window_s = 0.5", "shot_window_s = 1e-300", "shot_window_s"),
        ("recoil_s = 0.02", "recoil_s = 1e308", "recoil_s"),
        ("cannon_cycle_s = 45.0", "cannon_cycle_s = 1e308", "cannon_cycle_s"),
        ("position_uncertainty_m = 0.000127", "position_uncertainty_m = 1e300", "position_uncertainty_m"),
    ],
)
def test_rig_config_out_of_bounds(tmp_path: Path, old: str, new: str, needle: str) -> None:
    refused(certify(tmp_path, config=sim_rig(old, new)), needle)


@pytest.mark.parametrize(
    ("scene", "needle"),
    [
        ("[cannon]\nfill_rate_kpa_s = 1e-300\n", "fill_rate_kpa_s"),
        ("[rig]\ntick_ns = 1e-300\n", "tick_ns"),
        ("[ball]\nm1 = 1e300\n", "m1"),
        ("[bat]\nhoop_hz = 1.0\n", "hoop_hz"),
    ],
)
def test_scene_file_out_of_bounds(tmp_path: Path, scene: str, needle: str) -> None:
    refused(certify(tmp_path, scene=scene), needle)


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("limit = 0.500", "limit = -1", "limit"),
        ("limit = 0.500", "limit = 1e300", "limit"),
        ("ring_check = false", 'ring_check = "yes"', "ring_check"),
        ("step_in = 0.5", "step_in = 5e-324", "step_in"),
        (
            "valid_hits = 2",
            "valid_hits = 2\n[procedure.environment]\ntemperature_c = [26.0, 18.0]",
            "temperature_c",
        ),
    ],
)
def test_procedure_out_of_bounds(tmp_path: Path, old: str, new: str, needle: str) -> None:
    assert old in QUICK_PROCEDURE
    refused(certify(tmp_path, procedure=QUICK_PROCEDURE.replace(old, new)), needle)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["model", "cor", "--speed", "1e-300", "--rigid"], "speed"),
        (["model", "cor", "--speed", "60", "--hoop", "1e300"], "hoop_hz"),
        (
            ["model", "bat", "--speed", "60", "--rigid", "--moi", "0.2", "--impact-from-pivot", "1e300"],
            "impact_from_pivot",
        ),
        (
            ["model", "bat", "--speed", "60", "--rigid", "--moi", "1e300", "--impact-from-pivot", "0.5"],
            "moi_kgm2",
        ),
        (["model", "cor", "--speed", "60", "--rigid", "--set", "k1=1e300"], "k1"),
        (["model", "curve", "--speed", "60", "--hoop-min", "300", "--hoop-max", "1e300"], "hoop_max"),
        (["rig-study", "accuracy", "--repeats", "1000000"], "repeats"),
        (["modal", "simulate", "out.csv", "--hits", "100000000"], "hits"),
        (["modal", "simulate", "out.csv", "--interval", "1e300"], "interval"),
        (["modal", "simulate", "out.csv", "--hits", "3", "--double-hit", "5"], "double-hit"),
    ],
)
def test_flags_out_of_bounds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, argv: list[str], needle: str
) -> None:
    monkeypatch.chdir(tmp_path)
    refused(run_cli(argv), needle)


def test_curve_points_are_capped_at_once() -> None:
    # 10 million points ran for minutes; the cap answers at once and says why
    t0 = time.perf_counter()
    result = run_cli(
        ["model", "curve", "--speed", "60", "--hoop-min", "300", "--hoop-max", "5000", "--points", "10000000"]
    )
    assert time.perf_counter() - t0 < 2.0
    refused(result, "points", "2000")


def test_study_refuses_a_binary_file(tmp_path: Path) -> None:
    data = tmp_path / "pop.csv"
    data.write_bytes(bytes(range(256)) * 8)
    refused(run_cli(["rig-study", "population", "--data", str(data)]), "pop.csv")


def test_study_refuses_nul_bytes_in_an_ascii_file(tmp_path: Path) -> None:
    data = tmp_path / "pop.csv"
    data.write_bytes(b"bat_id,barrel,hoop_hz\nA\x00,wood,1800\n")
    refused(run_cli(["rig-study", "population", "--data", str(data)]), "pop.csv")


def test_study_refuses_a_hoop_frequency_no_bat_has(tmp_path: Path) -> None:
    data = tmp_path / "pop.csv"
    data.write_text("bat_id,barrel,hoop_hz\nA,aluminium,1800\nB,aluminium,1e300\n")
    refused(run_cli(["rig-study", "population", "--data", str(data)]), "hoop_hz")


# The bounds must not refuse a real bat or a real model question: their edges are accepted.
@pytest.mark.parametrize("hoop", ["20", "10000"])
def test_the_hoop_range_edges_run_the_model(hoop: str) -> None:
    for speed in ("1", "100"):
        assert run_cli(["model", "cor", "--speed", speed, "--hoop", hoop, "--json"]).code == 0


def test_the_model_refuses_below_its_hoop_range() -> None:
    refused(run_cli(["model", "cor", "--speed", "60", "--hoop", "19", "--json"]), "hoop")


@pytest.mark.parametrize("hoop", [200.0, 10000.0])
def test_a_bat_at_the_hoop_range_edges_is_certified(tmp_path: Path, hoop: float) -> None:
    result = certify(tmp_path, bat=GOOD_BAT.replace("hoop_hz = 3600.0", f"hoop_hz = {hoop}"))
    assert result.code in (0, 1), result.err
    assert result.stray_runs == []


@pytest.mark.parametrize(
    "where",
    [
        {"config": sim_rig('"sim://cannon?scene=ideal"', '"nan"')},  # a port that cannot be opened
    ],
)
def test_mid_run_errors_record_the_interruption(tmp_path: Path, where: dict[str, str]) -> None:
    result = certify(tmp_path, **where)
    assert result.code in (0, 1, 2, 3) and "Traceback" not in result.err
    assert result.stray_runs == [], result.err
