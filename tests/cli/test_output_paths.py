"""Where a command writes: --output, --plot, a positional OUT, --figures and --plot-dir (issue 21, item 12).

A file flag given a folder is an error (before, `--plot DIR` wrote DIR.png and DIR.svg beside the
folder); a file or folder whose parent folder does not exist is refused, not created (before,
missing folders were made silently). Each is one line naming the path, exit 2, before any work
is done and with nothing written.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.ball.data import write_ccor_csv
from tests.ball.synthetic import ccor_points
from tests.unit.clirun import ROOT, main

POPULATION = str(ROOT / "protocols" / "examples" / "population.csv")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """A CCOR data file and a modal recording to read."""
    d = tmp_path_factory.mktemp("inputs")
    ccor = write_ccor_csv(ccor_points(seed=0, with_u=True), d / "ccor.csv")
    rec = d / "rec.csv"
    assert main(["modal", "simulate", str(rec), "--hits", "2", "--interval", "0.1", "--hoop", "1800"]) == 0
    return {"CCOR": str(ccor), "REC": str(rec), "DB": str(d / "none.db")}


# (argv with TARGET where the path goes; what the flag expects)
FILE_FLAGS: list[tuple[str, ...]] = [
    ("model", "curve", "--speed", "60", "--hoop-min", "500", "--hoop-max", "3000", "--points", "3", "--plot"),
    ("rig-study", "accuracy", "--quick", "--repeats", "1", "--plot"),
    ("model", "calibrate", "--data", POPULATION, "--output"),
    ("model", "fit-ball", "--data", "CCOR", "--output"),
    ("model", "fit-ball", "--data", "CCOR", "--output", "OTHER/ball.json", "--plot"),
    ("modal", "analyze", "REC", "--plot"),
    ("modal", "simulate", "--hits", "2", "--interval", "0.1"),  # OUT: the positional argument
    ("balls", "law", "LOT-1", "--db", "DB", "--output"),
    ("report", "last", "--db", "STORE", "--format", "md", "--output"),
    ("export", "--db", "STORE", "--view", "shots", "--output"),
]
DIR_FLAGS: list[tuple[str, ...]] = [
    ("rig-study", "population", "--data", POPULATION, "--plot-dir"),
    ("report", "last", "--db", "STORE", "--format", "md", "--output", "OTHER/c.md", "--figures"),
]


def _argv(template: tuple[str, ...], target: str, inputs: dict[str, str], other: Path) -> list[str]:
    out = []
    for a in template:
        if a.startswith("OTHER/"):
            out.append(str(other / a.removeprefix("OTHER/")))
        else:
            out.append(inputs.get(a, a))
    return [*out, target]


def _refused(capsys: pytest.CaptureFixture[str], code: int, needle: str, *words: str) -> None:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert needle in lines[0] and all(w in lines[0] for w in words), lines[0]


@pytest.fixture
def all_inputs(inputs: dict[str, str], store_db: Path) -> dict[str, str]:
    return {**inputs, "STORE": str(store_db)}


@pytest.mark.parametrize("template", FILE_FLAGS, ids=lambda t: " ".join(t[:2]) + " " + t[-1])
def test_a_file_in_a_missing_folder_is_refused_and_no_folder_made(
    template: tuple[str, ...], all_inputs: dict[str, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "no" / "such" / "out.png"
    code = main(_argv(template, str(target), all_inputs, tmp_path))
    _refused(capsys, code, str(target), "does not exist")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("template", FILE_FLAGS, ids=lambda t: " ".join(t[:2]) + " " + t[-1])
def test_a_folder_where_a_file_is_expected_is_refused(
    template: tuple[str, ...], all_inputs: dict[str, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "figs"
    folder.mkdir()
    code = main(_argv(template, str(folder), all_inputs, tmp_path))
    _refused(capsys, code, str(folder), "folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figs"]  # no figs.png, figs.svg beside it
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("template", DIR_FLAGS, ids=lambda t: " ".join(t[:2]) + " " + t[-1])
def test_a_folder_flag_refuses_a_missing_parent_and_a_file(
    template: tuple[str, ...], all_inputs: dict[str, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "no" / "figures"
    _refused(capsys, main(_argv(template, str(target), all_inputs, tmp_path)), str(target), "does not exist")
    assert list(tmp_path.iterdir()) == []
    a_file = tmp_path / "figures"
    a_file.write_text("not a folder")
    _refused(capsys, main(_argv(template, str(a_file), all_inputs, tmp_path)), str(a_file), "not a folder")


def test_a_folder_flag_still_makes_its_own_folder(
    all_inputs: dict[str, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--figures DIR in an existing folder: DIR is made (make demo relies on it)."""
    out = tmp_path / "c.md"
    argv = ["report", "last", "--db", all_inputs["STORE"], "--format", "md", "--output", str(out)]
    assert main([*argv, "--figures", str(tmp_path / "figures")]) == 0
    assert (tmp_path / "figures").is_dir() and out.is_file()
