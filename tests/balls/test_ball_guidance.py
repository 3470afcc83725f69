"""The guidance names the ball test of the lot's and the procedure's balls (a fastpitch lot's is
ball-cor-fastpitch, not ball-cor), and a ball test firing balls the lot is not registered as (its
mass, a softball's class) is refused before firing, in one line, recording nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.balls.test_balls_cli import LOT, entries, stdout_of
from tests.unit.clirun import run_cli

ROOT = Path(__file__).resolve().parents[2]
FASTPITCH = LOT.replace('id = "ACME-1"', 'id = "FP-1"').replace("nominal_cor = 0.52", "nominal_cor = 0.47")
FASTPITCH = FASTPITCH.replace("cor_tolerance = 0.02", "cor_tolerance = 0.02\nmass_kg = 0.187")
BASEBALL = LOT.replace("cor_tolerance = 0.02", "cor_tolerance = 0.02\nmass_kg = 0.145")


def _register(tmp_path: Path, text: str) -> Path:
    (tmp_path / "lot.toml").write_text(text, encoding="utf-8")
    db = tmp_path / "b.db"
    assert run_cli(["balls", "register", str(tmp_path / "lot.toml"), "--db", str(db)]).code == 0
    return db


@pytest.mark.parametrize(
    ("text", "lot", "named"),
    [(FASTPITCH, "FP-1", "ball-cor-fastpitch"), (BASEBALL, "ACME-1", "ccor|ball-cor")],
    ids=["fastpitch", "baseball"],
)
def test_balls_show_names_the_tests_of_the_lots_balls(
    tmp_path: Path, text: str, lot: str, named: str
) -> None:
    db = _register(tmp_path, text)
    code, out = stdout_of(["balls", "show", lot, "--db", str(db)])
    assert code == 0
    assert f"no results yet: rig balls test --procedure {named} --lot {lot}" in out


@pytest.mark.parametrize("dry", [False, True])
def test_a_ball_test_of_other_balls_than_the_lots_is_refused_before_firing(tmp_path: Path, dry: bool) -> None:
    db = _register(tmp_path, FASTPITCH)
    before = entries(db)
    argv = ["balls", "test", "--procedure", "ball-cor", "--lot", "FP-1", "--sim", "lab", "--db", str(db)]
    result = run_cli(argv + (["--dry-run"] if dry else []))
    assert result.code == 2 and result.err.count("\n") == 1, result.err
    assert "mass 0.187 kg" in result.err and "0.145 kg" in result.err
    assert "--procedure ball-cor-fastpitch" in result.err
    assert entries(db) == before
    # the fastpitch balls of the fastpitch lot pass this check (the dry run fits them)
    argv[3] = "ball-cor-fastpitch"
    argv[argv.index("lab")] = "softball"
    ok = run_cli([*argv, "--dry-run"])
    assert ok.code == 0, ok.err


def test_a_fastpitch_bpf_on_an_untested_lot_names_the_fastpitch_ball_test(tmp_path: Path) -> None:
    db = _register(tmp_path, FASTPITCH)
    bat = str(ROOT / "protocols" / "examples" / "softball-bat.toml")
    argv = [
        "certify",
        "--procedure",
        "fastpitch-bpf",
        "--bat",
        bat,
        "--sim",
        "softball",
        "--ball-lot",
        "FP-1",
    ]
    result = run_cli([*argv, "--db", str(db)])
    assert result.code == 2 and result.err.count("\n") == 1, result.err
    assert "'rig balls test --procedure ball-cor-fastpitch --lot FP-1'" in result.err


@pytest.mark.parametrize(
    ("name", "lot", "test", "scene", "other"),
    [
        ("ball-lot.toml", "ACME-23A", "ball-cor", "lab", "ball-cor-fastpitch"),
        ("ball-lot-fastpitch.toml", "FP-23A", "ball-cor-fastpitch", "softball", "ball-cor"),
    ],
)
def test_the_example_lots_register_and_fit_their_ball_tests(
    tmp_path: Path, name: str, lot: str, test: str, scene: str, other: str
) -> None:
    """The example lots of docs/ball.md: registered, their own test named and dry-run clean on the
    scene that loads their balls, the other ball's test refused."""
    db = tmp_path / "x.db"
    assert (
        run_cli(["balls", "register", str(ROOT / "protocols" / "examples" / name), "--db", str(db)]).code == 0
    )
    _, out = stdout_of(["balls", "show", lot, "--db", str(db)])
    named = out.splitlines()[-1].split("--procedure ", 1)[1].split()[0].split("|")
    assert test in named and other not in named
    argv = ["balls", "test", "--lot", lot, "--sim", scene, "--db", str(db), "--dry-run", "--procedure"]
    ok = run_cli([*argv, test])
    assert ok.code == 0, ok.err
    refused = run_cli([*argv, other])
    assert refused.code == 2 and f"--procedure {test}" in refused.err
