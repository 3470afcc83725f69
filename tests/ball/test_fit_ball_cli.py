"""`rig model fit-ball` and `--ball` from the command line: output, files, refusals, hostile inputs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.ball.data import write_ccor_csv
from rig.cli import main
from rig.physics import DEFAULT_PARAMS, rigid_cor
from rig.physics.ball_law import BallLaw
from rig.population import write_population_csv
from rig.population.calfile import load_calibration
from tests.ball.synthetic import SPEEDS, TRUE, ccor_points

GOOD_HEADER = "speed_m_s,ccor,u_ccor,ball_id\n"


@pytest.fixture(scope="module")
def ccor_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_ccor_csv(ccor_points(seed=0, with_u=True), tmp_path_factory.mktemp("ccor") / "ccor.csv")


@pytest.fixture(scope="module")
def ball_file(ccor_csv: Path) -> Path:
    out = ccor_csv.with_name("ball.json")
    assert main(["model", "fit-ball", "--data", str(ccor_csv), "--lot", "LOT-7", "--output", str(out)]) == 0
    return out


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    got = capsys.readouterr()
    return code, got.out, got.err


def test_prints_estimates_covariance_scatter_loo_and_the_choice(
    ccor_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run(
        ["model", "fit-ball", "--data", str(ccor_csv), "--output", str(tmp_path / "b.json")], capsys
    )
    assert code == 0, err
    for needle in (
        "Covariance of a+b",
        "correlation a-b: +0.99",
        "residual scatter",
        "leave-one-out RMSE",
        "chosen: a+b",
        "not identified by these data: a+b+c1, a+b+k1+c1",
        "20 CCOR points (20 balls, 5 speeds, 25.0-60.0 m/s)",
    ):
        assert needle in out, needle
    assert "wrote" in err


def test_ball_file_records_constants_variant_covariance_and_provenance(
    ball_file: Path, ccor_csv: Path
) -> None:
    import hashlib

    law = BallLaw.load(ball_file)
    assert law.variant == "a+b" and law.lot == "LOT-7"
    assert set(law.constants) == {"m1", "k1", "c1", "a", "b"}
    assert law.constants["k1"] == DEFAULT_PARAMS.k1 and law.constants["a"] == law.parameters["a"]
    assert abs(law.parameters["a"] - TRUE["a"]) <= 2 * law.uncertainty["a"]
    prov = law.provenance
    assert prov.data_sha256 == hashlib.sha256(ccor_csv.read_bytes()).hexdigest()
    assert (prov.n_points, prov.n_balls, prov.n_speeds) == (20, 20, 5)
    assert (prov.speed_min_m_s, prov.speed_max_m_s) == (25.0, 60.0)
    assert set(prov.fixed) == {"m1", "k1", "c1"} and "paper" in prov.fixed["k1"]
    assert prov.software.startswith("rig ") and prov.created_utc.endswith("+00:00")
    assert len(law.covariance) == 2 and law.correlation_ab is not None
    assert law.params.m2 == DEFAULT_PARAMS.m2  # the barrel's constants are not the ball's


def test_json_output_is_the_file_record(
    ccor_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out_file = tmp_path / "b.json"
    code, out, _ = run(
        ["model", "fit-ball", "--data", str(ccor_csv), "--output", str(out_file), "--json"], capsys
    )
    assert code == 0
    printed = json.loads(out)
    assert printed["kind"] == "rig-ball-law" and printed["variant"] == "a+b"
    assert printed["parameters"] == json.loads(out_file.read_text())["parameters"]


def test_set_fixes_the_ball_mass_and_records_its_source(
    ccor_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out_file = tmp_path / "b.json"
    argv = ["model", "fit-ball", "--data", str(ccor_csv), "--output", str(out_file), "--set", "m1=0.1445"]
    assert run(argv, capsys)[0] == 0
    law = BallLaw.load(out_file)
    assert law.constants["m1"] == 0.1445 and "--set m1=0.1445" in law.provenance.fixed["m1"]
    code, _, err = run([*argv[:-1], "a=0.7"], capsys)
    assert code == 2 and "only m1, k1, c1 can be fixed" in err


def test_plot_writes_png_and_svg(ccor_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fig = tmp_path / "fig3.png"
    argv = [
        "model",
        "fit-ball",
        "--data",
        str(ccor_csv),
        "--output",
        str(tmp_path / "b.json"),
        "--plot",
        str(fig),
    ]
    assert run(argv, capsys)[0] == 0
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in fig.with_suffix(".svg").read_bytes()[:500]


HOSTILE = [
    ("", "empty file"),
    ("speed_m_s,ccor\n", "a header but no rows"),
    ("speed,ccor\n25,0.5\n", "unknown column(s) speed"),
    ("ccor,ball_id\n0.5,B1\n", "missing column(s) speed_m_s"),
    ("speed_m_s,ccor\n25,0.52\n33,abc\n", "line 3: ccor 'abc' is not a number"),
    ("speed_m_s,ccor\n# a comment\n25,0.52\n33,nan\n", "line 4: ccor 'nan' is not a finite number"),
    ("speed_m_s,ccor\n25,inf\n", "line 2: ccor 'inf' is not a finite number"),
    ("speed_m_s,ccor\n25,0.52,9\n", "line 2: 3 cells, the header has 2"),
    ("speed_m_s,ccor\n250,0.52\n", "line 2: speed_m_s 250 outside 1-100 m/s"),
    ("speed_m_s,ccor\n25,1.3\n", "line 2: ccor 1.3 outside 0-1"),
    ("speed_m_s,ccor\n25,0.5\n33,0.49\n42,0.48\n51,0.47\n", "too few distinct speeds: 4"),
    ("speed_m_s,ccor\n" + "".join(f"{v},0.5\n" for v in (40, 44, 48, 52, 56, 60)), "ratio 1.50"),
    (GOOD_HEADER + "25,0.52,,B1\n", "some points but not all"),
]


@pytest.mark.parametrize(("text", "needle"), HOSTILE)
def test_hostile_or_unfit_csv_is_refused_with_one_line(
    text: str, needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "bad.csv"
    data.write_text(text, encoding="utf-8")
    if needle == "some points but not all":
        good = "".join(f"{v},{0.5 - 0.0005 * v},0.001,B{v}\n" for v in SPEEDS)
        data.write_text(text + good, encoding="utf-8")
    code, _, err = run(
        ["model", "fit-ball", "--data", str(data), "--output", str(tmp_path / "b.json")], capsys
    )
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("rig: ") and needle in err, err
    assert not (tmp_path / "b.json").exists()


def test_binary_huge_and_missing_files_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    binary = tmp_path / "bin.csv"
    binary.write_bytes(b"speed_m_s,ccor\n\x00\x01\x02")
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"speed_m_s,ccor\n25,0.5\xe9\n")
    huge = tmp_path / "huge.csv"
    with huge.open("wb") as fh:
        fh.truncate(11_000_000)
    for path, needle in (
        (binary, "NUL bytes"),
        (latin, "not a UTF-8 text file"),
        (huge, "larger than 10000000 bytes"),
        (tmp_path / "absent.csv", "no such file"),
        (tmp_path, "a directory"),
    ):
        code, _, err = run(
            ["model", "fit-ball", "--data", str(path), "--output", str(tmp_path / "b.json")], capsys
        )
        assert code == 2 and needle in err and err.count("\n") == 1, err


def test_json_refusal_is_an_error_object(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "few.csv"
    data.write_text("speed_m_s,ccor\n25,0.5\n60,0.48\n", encoding="utf-8")
    code, out, _ = run(
        ["model", "fit-ball", "--data", str(data), "--output", str(tmp_path / "b.json"), "--json"], capsys
    )
    assert code == 2
    error = json.loads(out)["error"]
    assert error["kind"] == "BallFitRefused" and "too few distinct speeds: 2" in error["message"]


def test_ball_changes_rig_model_cor_by_the_ball_law(
    ball_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    law = BallLaw.load(ball_file)
    code, out, _ = run(
        ["model", "cor", "--speed", "40", "--rigid", "--ball", str(ball_file), "--json"], capsys
    )
    assert code == 0
    with_ball = json.loads(out)
    _, out, _ = run(["model", "cor", "--speed", "40", "--rigid", "--json"], capsys)
    paper = json.loads(out)
    assert with_ball["cor"] == pytest.approx(rigid_cor(law.params, 40.0), abs=1e-9)
    assert paper["cor"] == pytest.approx(rigid_cor(DEFAULT_PARAMS, 40.0), abs=1e-9)
    assert abs(with_ball["cor"] - paper["cor"]) > 1e-3  # a = 0.70, b = 0.55 is not the paper's ball
    assert with_ball["ball"]["lot"] == "LOT-7" and with_ball["params"]["a"] == law.constants["a"]
    code, _, err = run(
        ["model", "cor", "--speed", "40", "--rigid", "--ball", str(ball_file), "--set", "a=0.6"], capsys
    )
    assert code == 2 and "--set a and --ball exclude each other" in err


def test_ball_reaches_curve_and_bat(ball_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    law = BallLaw.load(ball_file)
    argv = ["model", "curve", "--speed", "60.8", "--hoop-min", "1000", "--hoop-max", "2000", "--points", "3"]
    code, out, _ = run([*argv, "--ball", str(ball_file), "--json"], capsys)
    assert code == 0
    assert json.loads(out)["cor_rigid"] == pytest.approx(rigid_cor(law.params, 60.8), abs=1e-9)
    bat = ["model", "bat", "--speed", "60.8", "--hoop", "1500", "--moi", "0.19", "--impact-from-pivot", "0.6"]
    _, with_ball, _ = run([*bat, "--ball", str(ball_file), "--json"], capsys)
    _, paper, _ = run([*bat, "--json"], capsys)
    assert json.loads(with_ball)["e_a"] != json.loads(paper)["e_a"]


def _population(tmp_path: Path) -> Path:
    from tests.population.test_calibrate import population

    return write_population_csv(population(n=12, seed=4), tmp_path / "pop.csv")


def test_calibration_records_its_ball_and_crosscheck_refuses_another(
    ball_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pop = _population(tmp_path)
    cal = tmp_path / "cal.json"
    code, out, err = run(
        ["model", "calibrate", "--data", str(pop), "--output", str(cal), "--ball", str(ball_file)], capsys
    )
    assert code == 0, err
    assert "ball: ball.json (lot LOT-7" in out
    law, sha = BallLaw.read(ball_file)
    recorded = load_calibration(cal)
    assert recorded.ball is not None
    assert recorded.ball["sha256"] == sha and recorded.ball["lot"] == "LOT-7"
    assert recorded.ball["constants"] == law.constants
    assert recorded.model_params.a == law.constants["a"]  # the calibration solved with the ball's law
    # the same ball: accepted; another ball (the paper's, here refitted with k1 fixed higher): refused
    code, _, err = run(
        ["model", "crosscheck", "--data", str(pop), "--calibration", str(cal), "--ball", str(ball_file)],
        capsys,
    )
    assert code == 0, err
    other = tmp_path / "other.json"
    BallLaw.model_validate({**law.model_dump(), "constants": {**law.constants, "k1": 7e7}}).save(other)
    code, _, err = run(
        ["model", "crosscheck", "--data", str(pop), "--calibration", str(cal), "--ball", str(other)], capsys
    )
    assert code == 2 and "differs from the calibration's ball" in err and err.count("\n") == 1
    plain = tmp_path / "plain.json"
    assert run(["model", "calibrate", "--data", str(pop), "--output", str(plain)], capsys)[0] == 0
    assert load_calibration(plain).ball is None
    code, _, err = run(
        ["model", "crosscheck", "--data", str(pop), "--calibration", str(plain), "--ball", str(ball_file)],
        capsys,
    )
    assert code == 2 and "made with the paper's ball" in err
