"""The `rig model` commands: JSON shapes, consistency of the figures, errors without tracebacks."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Callable

import numpy as np
import pytest

from rig.cli import build_parser, main


def run_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_cor_json_has_the_promised_fields(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(capsys, "model", "cor", "--speed", "60.8", "--hoop", "1250")
    for key in ("cor", "cor_rigid", "efficiency", "contact_time_s"):
        assert isinstance(out[key], float)
    assert 0.0 < out["cor"] < 1.0
    assert out["efficiency"] == pytest.approx(out["cor"] / out["cor_rigid"], rel=1e-12)
    # 1250 Hz sits near the paper's optimum: the flexible barrel beats the rigid one
    assert out["efficiency"] > 1.3


def test_cor_rigid_has_unit_efficiency(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(capsys, "model", "cor", "--speed", "60.8", "--rigid")
    assert out["hoop_hz"] is None
    assert out["efficiency"] == pytest.approx(1.0, abs=1e-9)
    assert out["cor"] == pytest.approx(0.484, abs=1e-3)  # numerics.md anchor at 60.8 m/s


def test_cor_accepts_model_overrides(capsys: pytest.CaptureFixture[str]) -> None:
    base = run_json(capsys, "model", "cor", "--speed", "60.8", "--hoop", "1250")
    heavier = run_json(capsys, "model", "cor", "--speed", "60.8", "--hoop", "1250", "--set", "m2=0.2")
    assert heavier["params"]["m2"] == 0.2
    assert heavier["cor"] != base["cor"]


def test_curve_grid_is_even_and_optimum_near_paper(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(
        capsys,
        "model",
        "curve",
        "--speed",
        "60.8",
        "--hoop-min",
        "300",
        "--hoop-max",
        "5000",
        "--points",
        "1000",
    )
    hz = np.array(out["hoop_hz"])
    assert hz.size == len(out["efficiency"]) == 1000
    assert hz[0] == 300.0 and hz[-1] == 5000.0
    assert np.allclose(np.diff(hz), (5000 - 300) / 999)
    # the paper's Fig. 4 puts the optimum at about 1250 Hz
    assert 1200.0 < out["optimum_hz"] < 1350.0
    # refined between grid points: no worse than the best grid point
    assert out["optimum_efficiency"] >= max(out["efficiency"]) - 1e-9


def test_curve_plot_writes_png_and_svg(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "eta.png"
    assert (
        main(
            [
                "model",
                "curve",
                "--speed",
                "60.8",
                "--hoop-min",
                "500",
                "--hoop-max",
                "3000",
                "--points",
                "20",
                "--plot",
                str(target),
            ]
        )
        == 0
    )
    assert target.stat().st_size > 1000
    assert (tmp_path / "eta.svg").read_text().lstrip().startswith("<?xml")


def test_bat_json_obeys_eq5(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(
        capsys,
        "model",
        "bat",
        "--speed",
        "60.8",
        "--hoop",
        "1800",
        "--moi",
        "0.20",
        "--impact-from-pivot",
        "0.58",
    )
    k = 0.145 * 0.58**2 / 0.20
    assert out["k"] == pytest.approx(k, rel=1e-12)
    assert out["bbcor"] == pytest.approx(out["e_a"] * (1 + k) + k, rel=1e-12)
    assert 0.0 < out["e_a"] < out["bbcor"] < 1.0


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["model", "cor", "--speed", "0", "--hoop", "1250"], "speed"),
        (["model", "cor", "--speed", "nan", "--rigid"], "speed"),
        (["model", "cor", "--speed", "60", "--hoop", "-5"], "hoop_hz"),
        (["model", "cor", "--speed", "60", "--rigid", "--set", "a=1.5"], "a = 1.5"),
        (["model", "cor", "--speed", "60", "--rigid", "--set", "m1=-1"], "m1"),
        (["model", "cor", "--speed", "60", "--rigid", "--set", "bogus=1"], "bogus"),
        (["model", "cor", "--speed", "60", "--rigid", "--rtol", "0.5"], "rtol"),
        (["model", "curve", "--speed", "60", "--hoop-min", "900", "--hoop-max", "800"], "hoop_max"),
        (
            ["model", "bat", "--speed", "60", "--rigid", "--moi", "0.01", "--impact-from-pivot", "0.6"],
            "moi_kgm2",
        ),
    ],
)
def test_bad_input_is_one_line_naming_the_parameter(
    capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert needle in err


def all_commands(parser: argparse.ArgumentParser) -> list[list[str]]:
    """Every command and subcommand of a command line's parser (rig's, rig-study's), as argv."""
    found: list[list[str]] = [[]]
    for action in parser._subparsers._group_actions:  # type: ignore[union-attr]
        for name, sub in action.choices.items():
            found.append([name])
            for sub_action in sub._subparsers._group_actions if sub._subparsers else []:
                found.extend([name, leaf] for leaf in sub_action.choices)
    return found


@pytest.mark.parametrize("argv", all_commands(build_parser()), ids=lambda a: " ".join(a) or "rig")
def test_every_command_has_help(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    has_help(main, argv, capsys)


def has_help(entry: Callable[[list[str]], int], argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """`ARGV --help` exits 0 and prints a usage."""
    with pytest.raises(SystemExit) as exc:
        entry([*argv, "--help"])
    assert exc.value.code == 0
    assert "usage:" in capsys.readouterr().out


@pytest.mark.usefixtures("cpu_load")
def test_module_entry_point_runs_in_a_fresh_process() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "rig.cli", "model", "cor", "--speed", "30", "--rigid", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["cor"] > 0.5
