"""`rig balls register|test|list|show` and `rig report` of a ball test, in process (rig.cli.main)."""

from __future__ import annotations

import io
import json
import sqlite3
from contextlib import closing, redirect_stdout
from pathlib import Path

import pytest

from rig.cli import main
from tests.unit.clirun import run_cli

LOT = """
[lot]
id = "ACME-1"
maker = "Acme"
model = "NCAA-1"
balls = 24
[lot.specification]
nominal_cor = 0.52
cor_tolerance = 0.02
[lot.conditioning]
temperature_c = 21.0
humidity_pct = 50.0
days = 14
"""


def entries(db: Path) -> int:
    with closing(sqlite3.connect(db)) as conn:
        return conn.execute("SELECT count(*) FROM log").fetchone()[0]


def stdout_of(argv: list[str]) -> tuple[int, str]:
    buf = io.StringIO()
    with redirect_stdout(buf):
        code = main(argv)
    return code, buf.getvalue()


@pytest.fixture
def db(tmp_path: Path) -> Path:
    (tmp_path / "lot.toml").write_text(LOT, encoding="utf-8")
    where = tmp_path / "b.db"
    result = run_cli(["balls", "register", str(tmp_path / "lot.toml"), "--db", str(where)])
    assert result.code == 0, result.err
    return where


@pytest.mark.parametrize(
    ("text", "named"),
    [
        (LOT.replace('maker = "Acme"\n', ""), "lot.maker"),  # a missing field
        (LOT.replace("balls = 24", "balls = 0"), "lot.balls"),  # a bad value
        (LOT.replace("nominal_cor = 0.52", "nominal_cor = 1.7"), "lot.specification.nominal_cor"),
        (LOT.replace('id = "ACME-1"', 'id = "../../etc/passwd"'), "lot.id"),  # a hostile id
        (LOT.replace("days = 14", "days = nan"), "lot.conditioning.days"),
        ("[lot]\nid = 'X'\nmaker = 'a'\nmodel = 'b'\nsurprise = 1\n", "lot.surprise"),  # an unknown field
        ("other = 1\n", "[lot]"),  # no [lot] table
        ("[lot\nid = 1\n", "not valid TOML"),
    ],
)
def test_a_bad_register_file_gives_one_line_naming_the_cause(tmp_path: Path, text: str, named: str) -> None:
    (tmp_path / "bad.toml").write_text(text, encoding="utf-8")
    result = run_cli(["balls", "register", str(tmp_path / "bad.toml"), "--db", str(tmp_path / "b.db")])
    assert result.code == 2
    lines = result.err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0] and "Traceback" not in result.err, result.err


def test_a_binary_register_file_is_refused_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "bin.toml").write_bytes(b"\x00\xff\xfe garbage \x89PNG")
    result = run_cli(["balls", "register", str(tmp_path / "bin.toml"), "--db", str(tmp_path / "b.db")])
    assert result.code == 2 and len(result.err.strip().splitlines()) == 1 and "bin.toml" in result.err


def test_register_twice_is_refused(db: Path, tmp_path: Path) -> None:
    result = run_cli(["balls", "register", str(tmp_path / "lot.toml"), "--db", str(db)])
    assert result.code == 2 and "already registered" in result.err


def test_a_dry_run_writes_nothing(db: Path) -> None:
    before = entries(db)
    result = run_cli(
        [
            "balls",
            "test",
            "--procedure",
            "ball-cor",
            "--lot",
            "ACME-1",
            "--sim",
            "lab",
            "--db",
            str(db),
            "--dry-run",
        ]
    )
    assert result.code == 0 and "dry run: the test fits" in result.err, result.err
    assert entries(db) == before


def test_a_dry_run_names_what_the_rig_cannot_do(db: Path, tmp_path: Path) -> None:
    rig = tmp_path / "rig.toml"
    rig.write_text(
        '[ports]\ncannon = "sim://cannon"\ngates = "sim://gates"\nclamp = "sim://clamp"\n', encoding="utf-8"
    )
    result = run_cli(
        [
            "balls",
            "test",
            "--procedure",
            "ccor",
            "--lot",
            "ACME-1",
            "--config",
            str(rig),
            "--db",
            str(db),
            "--dry-run",
        ]
    )
    assert result.code == 2 and "outside the aim calibration" in result.err


def test_an_unregistered_lot_is_named(db: Path) -> None:
    result = run_cli(
        ["balls", "test", "--procedure", "ball-cor", "--lot", "NOPE", "--sim", "lab", "--db", str(db)]
    )
    assert result.code == 2 and "ACME-1" in result.err and "register" in result.err


def test_ball_cor_on_the_lab_rig_then_list_show_report_verify(db: Path, tmp_path: Path) -> None:
    code, text = stdout_of(
        [
            "balls",
            "test",
            "--procedure",
            "ball-cor",
            "--lot",
            "ACME-1",
            "--sim",
            "lab",
            "--db",
            str(db),
            "--json",
        ]
    )
    assert code == 0
    done = json.loads(text)
    r = done["lot_result"]
    assert 0.50 < r["mean"] < 0.53 and r["n_balls"] == 6 and r["hits_per_ball"] == 4
    assert r["points"][0]["ball_id"] == "ACME-1-01" and r["points"][-1]["ball_id"] == "ACME-1-06"
    code, text = stdout_of(["balls", "list", "--db", str(db), "--json"])
    listed = json.loads(text)
    assert listed[0]["lot"]["id"] == "ACME-1" and listed[0]["latest"]["mean"] == r["mean"]
    code, text = stdout_of(["balls", "show", "ACME-1", "--db", str(db)])
    assert "ACME-1" in text and done["run_id"] in text
    for fmt, mark in (
        ("md", "# Ball-lot report: ACME-1"),
        ("html", "<h1>Ball-lot report"),
        ("json", '"lot_result"'),
    ):
        out = tmp_path / f"report.{fmt}"
        result = run_cli(["report", "last", "--db", str(db), "--format", fmt, "--output", str(out)])
        assert result.code == 0, result.err
        assert mark in out.read_text(encoding="utf-8")
    code, text = stdout_of(["verify", "--db", str(db)])
    assert code == 0 and text.startswith("ok:")


def test_a_ball_test_run_again_meets_its_own_simulated_noise(db: Path, tmp_path: Path) -> None:
    """Two ball-cor tests of one lot at the same hour of the simulated lab: each run is its own
    session of the lab (the store's count of runs), so they do not repeat each other's numbers,
    which would make a fit over both count every hit twice."""
    from tests.ball.test_fit_ball_store import smaller

    small = smaller("ball-cor", tmp_path, balls_per_speed=2)
    results = []
    for _ in range(2):
        argv = [
            "balls",
            "test",
            "--procedure",
            str(small),
            "--lot",
            "ACME-1",
            "--sim",
            "lab",
            "--db",
            str(db),
        ]
        code, out = stdout_of([*argv, "--json"])
        assert code == 0
        results.append(json.loads(out)["lot_result"])
    speeds = [[p["speed_m_s"] for p in r["points"]] for r in results]
    assert speeds[0] != speeds[1] and results[0]["mean"] != results[1]["mean"]
