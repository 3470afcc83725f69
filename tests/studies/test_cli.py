"""`rig-study population`: JSON shapes, files written, one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from studies.cli import build_parser, main
from tests.unit.test_cli import all_commands, has_help


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_study_json_and_plots(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "population", "--json", "--plot-dir", str(tmp_path))
    assert code == 0 and "SYNTHETIC" in err
    d = json.loads(out)
    assert d["synthetic"] is True and d["n_bats"] == 48
    assert {"aluminium", "composite"} == set(d["materials"])
    assert len(d["fig5"]) == 48
    assert d["fig6"]["bin_width_hz"] == 50.0 and d["fig6"]["half_width_hz"] == 25.0
    for name in ("besr", "bbs", "bbcor"):
        bins = d["fig6"]["metrics"][name]
        assert all({"center_hz", "n", "mean", "std"} <= b.keys() for b in bins)
        assert len(d["model"][name]) == len(d["model"]["hoop_hz"])
    for name in ("fig5-hoop-vs-bending", "fig6-metrics-vs-hoop"):
        assert (tmp_path / f"{name}.png").exists() and (tmp_path / f"{name}.svg").exists()


def test_study_table_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "population")
    assert code == 0 and "SYNTHETIC" in out and "per 1000 Hz" in out
    empty = tmp_path / "e.csv"
    empty.write_text("bat_id,barrel,hoop_hz\n")
    code, _, err = run(capsys, "population", "--data", str(empty))
    assert code == 2 and "no bats" in err
    code, _, err = run(capsys, "population", "--db", str(tmp_path / "absent.db"))
    assert code == 2 and err.startswith("rig-study: ")


@pytest.mark.parametrize("argv", all_commands(build_parser()), ids=lambda a: " ".join(a) or "rig-study")
def test_every_command_has_help(capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    has_help(main, argv, capsys)
