"""The calibrated cross-check: interval coverage, detection of altered bats, u_model against Monte Carlo.

Populations are made here one bat at a time with rig.physics.predict_bat and Eq. 5 written out
(BBCOR = e_A (1 + k) + k, k = m Q^2 / I), at 'true' m2, c2 far from the paper's, plus Gaussian
bat-to-bat scatter of known size; the calibration then fits them with its own batch code.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.stats import t as student_t

from rig.cli import main
from rig.core.errors import ConfigError
from rig.physics import DEFAULT_PARAMS, PivotedBat, predict_bat
from rig.population import write_population_csv
from rig.population.calfile import CalibrationFile, calibration_record, write_calibration
from rig.population.calibrate import calibrate
from rig.population.crosscheck import CrossCheckRefused, crosscheck_bats, crosscheck_one
from rig.population.dataset import PopulationBat

INCH = 0.0254
TRUE = {"m2": 0.15, "c2": 400.0}
SCATTER = 0.005


def true_bbcor(hoop: float, moi: float, length: float, loc: float) -> float:
    """The true model's BBCOR: single solve, Eq. 5 by hand, pivot 6 in from the knob."""
    params = DEFAULT_PARAMS.model_copy(update={"m1": 0.145, **TRUE})
    q = (length - loc - 6.0) * INCH
    e_a = predict_bat(params, 60.8, hoop, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)).e_a
    k = 0.145 * q * q / moi
    return e_a * (1.0 + k) + k


def bats(n: int, seed: int, shift: float = 0.0, prefix: str = "B") -> list[PopulationBat]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        length = float(rng.choice([31.0, 32.0, 33.0, 34.0]))
        moi = 0.19 + 0.012 * (length - 33.0) + float(rng.normal(0.0, 0.008))
        hoop = float(rng.uniform(1400.0, 3000.0))
        loc = float(rng.uniform(6.0, 7.0))
        value = true_bbcor(hoop, moi, length, loc) + shift + float(rng.normal(0.0, SCATTER))
        out.append(
            PopulationBat(
                bat_id=f"{prefix}{i:03d}",
                barrel="composite",
                hoop_hz=hoop,
                length_in=length,
                moi_kgm2=moi,
                location_in=loc,
                bbcor=value,
                source="synthetic test",
            )
        )
    return out


@pytest.fixture(scope="module")
def record() -> dict[str, Any]:
    fitted = calibrate(bats(40, seed=11), variants=("m2+c2",))
    return calibration_record(fitted, b"synthetic", "synthetic.csv")


@pytest.fixture(scope="module")
def cal(record: dict[str, Any]) -> CalibrationFile:
    return CalibrationFile.model_validate(record)


@pytest.fixture(scope="module")
def cal_path(record: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_calibration(record, tmp_path_factory.mktemp("cal") / "cal.json")


def test_interval_covers_95_percent_of_fresh_legal_bats(cal: CalibrationFile) -> None:
    fresh = bats(250, seed=12, prefix="F")
    checks = crosscheck_bats(cal, fresh)
    inside = [c.interval[0] <= c.measured <= c.interval[1] for c in checks if c.measured is not None]
    assert len(inside) == 250
    assert 0.90 <= np.mean(inside) <= 0.99
    assert np.mean([c.flagged for c in checks]) == pytest.approx(1.0 - np.mean(inside))
    # the interval's half-width is t(0.975, n - p) times the root sum of squares of the parts
    t = student_t.ppf(0.975, 38)
    for c in checks[:5]:
        u = math.sqrt(c.u_model**2 + c.u_scatter**2 + c.u_measured**2)
        assert (c.interval[1] - c.predicted) == pytest.approx(t * u, rel=1e-12)
        assert c.z == pytest.approx((c.measured - c.predicted) / u)
        assert c.u_scatter == cal.scatter and c.u_measured == 0.0 and not c.u_measured_known


def test_bats_altered_by_005_are_flagged(cal: CalibrationFile) -> None:
    altered = bats(60, seed=13, shift=0.05, prefix="A")
    checks = crosscheck_bats(cal, altered)
    assert all(c.flagged for c in checks)
    assert np.mean([c.z for c in checks]) == pytest.approx(0.05 / SCATTER, rel=0.2)


def test_prediction_is_the_true_model_within_its_u_model(cal: CalibrationFile) -> None:
    """Noise-free: the prediction misses the truth by about u_model, never by many of them."""
    clean = bats(40, seed=14, prefix="C")
    checks = crosscheck_bats(cal, clean)
    truth = [true_bbcor(b.hoop_hz, b.moi_kgm2, b.length_in, b.location_in) for b in clean]  # type: ignore[arg-type]
    z = [(c.predicted - t) / c.u_model for c, t in zip(checks, truth, strict=True)]
    assert max(abs(v) for v in z) < 5.0


def test_u_model_matches_a_monte_carlo_over_the_parameter_covariance(cal: CalibrationFile) -> None:
    """Parameters drawn from N(values, C), each bat re-solved by the single-solve path."""
    rng = np.random.default_rng(5)
    names = list(cal.parameters)
    mean = np.array([cal.parameters[n] for n in names])
    draws = rng.multivariate_normal(mean, np.array(cal.covariance), size=300)
    for hoop, moi, length, loc in (
        (1500.0, 0.18, 32.0, 6.2),
        (2200.0, 0.19, 33.0, 6.5),
        (2900.0, 0.2, 34.0, 6.8),
    ):
        q = (length - loc - 6.0) * INCH
        k = 0.145 * q * q / moi
        values = []
        for d in draws:
            params = DEFAULT_PARAMS.model_copy(update={"m1": 0.145, **dict(zip(names, d, strict=True))})
            e_a = predict_bat(params, 60.8, hoop, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)).e_a
            values.append(e_a * (1.0 + k) + k)
        check = crosscheck_one(cal, hoop, moi, length, loc, None, None)
        assert check.u_model == pytest.approx(np.std(values, ddof=1), rel=0.15)
        assert check.predicted == pytest.approx(np.mean(values), abs=0.3 * check.u_model)
        assert check.z is None and check.flagged is None


def test_own_uncertainty_widens_the_interval(cal: CalibrationFile) -> None:
    bat = bats(1, seed=15)[0]
    plain = crosscheck_bats(cal, [bat])[0]
    with_u = crosscheck_bats(cal, [bat], u_measured={bat.bat_id: 0.01})[0]
    from_column = crosscheck_bats(cal, [bat.model_copy(update={"u_bbcor": 0.01})])[0]
    assert with_u.u_measured == from_column.u_measured == 0.01
    assert with_u.interval == from_column.interval
    half = with_u.interval[1] - with_u.predicted
    assert half == pytest.approx(plain.t_factor * math.sqrt(plain.u_total**2 + 0.01**2), rel=1e-12)
    ninety = crosscheck_bats(cal, [bat], coverage=0.90)[0]
    assert ninety.interval[1] - ninety.predicted == pytest.approx(student_t.ppf(0.95, 38) * plain.u_total)


def test_outside_the_hoop_range_is_predicted_but_marked(cal: CalibrationFile) -> None:
    inside = crosscheck_one(cal, 2000.0, 0.19, 33.0, 6.5, 0.48, 0.004)
    outside = crosscheck_one(cal, 3900.0, 0.19, 33.0, 6.5, 0.48, 0.004)
    assert not inside.extrapolated and outside.extrapolated
    assert outside.predicted < inside.predicted  # stiffer barrel, less trampoline
    d = outside.as_dict()
    assert d["extrapolated"] and {"bat_id", "predicted", "measured", "interval", "flagged", "z"} <= set(d)


def test_refusals_name_the_cause(cal: CalibrationFile) -> None:
    bat = bats(1, seed=16)[0]
    with pytest.raises(CrossCheckRefused, match="missing column moi_kgm2"):
        crosscheck_bats(cal, [bat.model_copy(update={"moi_kgm2": None})])
    with pytest.raises(CrossCheckRefused, match="coverage"):
        crosscheck_bats(cal, [bat], coverage=1.0)
    with pytest.raises(CrossCheckRefused, match="off the barrel"):
        crosscheck_one(cal, 2000.0, 0.19, 33.0, 30.0, None, None)


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(["model", "crosscheck", *argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_cli_json_lists_each_bat(cal_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    legal, altered = bats(6, seed=17, prefix="L"), bats(6, seed=18, shift=0.05, prefix="X")
    data = write_population_csv(legal + altered, tmp_path / "bats.csv")
    rc, out, _ = _cli(capsys, "--data", str(data), "--calibration", str(cal_path), "--json")
    assert rc == 0
    rows = json.loads(out)
    assert [r["bat_id"] for r in rows] == [b.bat_id for b in legal + altered]
    assert all(r["flagged"] for r in rows[6:]) and sum(r["flagged"] for r in rows[:6]) <= 1
    for r, b in zip(rows, legal + altered, strict=True):
        assert r["measured"] == pytest.approx(b.bbcor)
        assert r["interval"][0] < r["predicted"] < r["interval"][1]
        assert r["coverage"] == 0.95 and r["u_model"] > 0 and r["u_scatter"] > 0
        truth = true_bbcor(b.hoop_hz, b.moi_kgm2, b.length_in, b.location_in)  # type: ignore[arg-type]
        assert abs(r["predicted"] - truth) < 4 * r["u_model"]


def test_cli_table_states_the_coverage(
    cal_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = write_population_csv(
        bats(3, seed=19) + bats(1, seed=20, shift=0.05, prefix="X"), tmp_path / "b.csv"
    )
    rc, out, _ = _cli(capsys, "--data", str(data), "--calibration", str(cal_path), "--coverage", "0.9")
    assert rc == 0
    assert "coverage 90 %" in out and "38 degrees of freedom" in out
    assert "FLAGGED" in out and "1 of 4 bats flagged" in out
    assert "give no u_bbcor" in out


@pytest.mark.parametrize(
    ("case", "cause"),
    [
        ("no-data", "no such file"),
        ("no-cal", "no such file"),
        ("bad-cal", "covariance must be"),
        ("no-metric", "no bbcor values"),
        ("coverage", "coverage 1.5 must lie between 0 and 1"),
        ("no-moi", "missing column moi_kgm2"),
    ],
)
def test_cli_refusals_are_one_line(
    case: str, cause: str, cal_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = bats(3, seed=21)
    if case == "no-metric":
        rows = [b.model_copy(update={"bbcor": None}) for b in rows]
    if case == "no-moi":
        rows = [b.model_copy(update={"moi_kgm2": None}) for b in rows]
    data = write_population_csv(rows, tmp_path / "b.csv")
    calibration = cal_path
    if case == "bad-cal":
        broken = json.loads(cal_path.read_text())
        broken["covariance"] = broken["covariance"][:1]
        calibration = tmp_path / "broken.json"
        calibration.write_text(json.dumps(broken))
    argv = ["--data", str(data), "--calibration", str(calibration)]
    if case == "no-data":
        argv[1] = str(tmp_path / "absent.csv")
    if case == "no-cal":
        argv[3] = str(tmp_path / "absent.json")
    if case == "coverage":
        argv += ["--coverage", "1.5"]
    rc, out, err = _cli(capsys, *argv)
    assert rc == 2 and out == ""
    assert "\n" not in err.strip() and cause in err


def test_cli_marks_a_bat_outside_the_hoop_range(
    cal_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bat = bats(1, seed=22)[0].model_copy(update={"hoop_hz": 3800.0})
    data = write_population_csv([bat], tmp_path / "b.csv")
    rc, out, _ = _cli(capsys, "--data", str(data), "--calibration", str(cal_path), "--json")
    assert rc == 0 and json.loads(out)[0]["extrapolated"] is True


def test_cli_warns_in_one_line_how_many_bats_lie_outside_the_calibrated_hoop_and_moi_range(
    cal_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Bats of another population were all flagged without a word that the calibration never saw
    their like: one warning line names how many lie outside its hoop-frequency or MOI range."""
    inside = bats(3, seed=23, prefix="IN")
    heavy = [b.model_copy(update={"moi_kgm2": 0.32, "bat_id": f"MOI{i}"}) for i, b in enumerate(bats(2, 24))]
    stiff = [bats(1, seed=25, prefix="HZ")[0].model_copy(update={"hoop_hz": 3800.0})]
    data = write_population_csv(inside + heavy + stiff, tmp_path / "other.csv")
    for extra in ((), ("--json",)):
        rc, out, err = _cli(capsys, "--data", str(data), "--calibration", str(cal_path), *extra)
        assert rc == 0
        (line,) = [x for x in err.splitlines() if "outside" in x]
        assert line.startswith("warning: 3 of 6 bats lie outside the calibrated range"), line
        assert "Hz" in line and "MOI" in line and "kg m" in line
    flags = {c["bat_id"]: c["extrapolated"] for c in json.loads(out)}
    assert [k for k, v in flags.items() if v] == ["MOI0", "MOI1", "HZ000"]


def test_model_bat_with_a_calibration(cal_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    q = (33.0 - 6.5 - 6.0) * INCH
    truth = true_bbcor(2400.0, 0.19, 33.0, 6.5)
    base = [
        "model",
        "bat",
        "--speed",
        "60.8",
        "--hoop",
        "2400",
        "--moi",
        "0.19",
        "--impact-from-pivot",
        str(q),
    ]
    argv = [*base, "--calibration", str(cal_path), "--measured", str(truth + 0.05), "--u-measured", "0.004"]
    assert main([*argv, "--json"]) == 0
    c = json.loads(capsys.readouterr().out)["calibrated"]
    assert abs(c["predicted"] - truth) < 4 * c["u_model"]
    half = student_t.ppf(0.975, 38) * math.sqrt(c["u_model"] ** 2 + c["u_scatter"] ** 2 + 0.004**2)
    assert c["interval"] == pytest.approx([c["predicted"] - half, c["predicted"] + half], rel=1e-12)
    assert c["flagged"] is True and c["z"] > 5 and not c["extrapolated"]
    assert c["calibration_provenance"]["n_bats"] == 40
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "95 % prediction interval" in text and "FLAGGED" in text and "40 bats" in text
    for extra, cause in (
        (["--speed", "50"], "--speed 50: the calibration predicts at 60.8 m/s"),
        (["--set", "m2=0.1"], "--set and --calibration exclude each other"),
    ):
        assert main([*argv, *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and cause in err, err
    assert main([*base, "--measured", "0.5"]) == 2
    assert "need --calibration" in capsys.readouterr().err


def test_the_uncertainty_columns_round_trip_and_stay_out_when_empty(tmp_path: Path) -> None:
    from rig.population import load_population

    rows = bats(3, seed=23)
    plain = write_population_csv(rows, tmp_path / "plain.csv")
    assert "u_bbcor" not in plain.read_text().splitlines()[0]
    rows[1] = rows[1].model_copy(update={"u_bbcor": 0.0042})
    back = load_population(write_population_csv(rows, tmp_path / "u.csv"))
    assert [b.u_bbcor for b in back] == [None, 0.0042, None] and back[1].u_metric("bbcor") == 0.0042
    (tmp_path / "bad.csv").write_text("bat_id,barrel,hoop_hz,u_bbcor\nX,wood,2000,-0.1\n")
    with pytest.raises(ConfigError, match="u_bbcor"):
        load_population(tmp_path / "bad.csv")


def test_a_fresh_crosscheck_loads_neither_numba_nor_scipy_stats_and_gives_the_compiled_figures(
    cal: CalibrationFile, cal_path: Path, tmp_path: Path
) -> None:
    """`rig model crosscheck` in a fresh process solves in numpy lanes (numba would take longer to
    load than the solves take) and takes t from rig.measure.student; its every figure is the one the
    compiled kernel gives in a process that has it loaded, within 1e-9."""
    from rig.physics import fast

    rows = bats(12, seed=24) + bats(4, seed=25, shift=0.03, prefix="X")
    data = write_population_csv(rows, tmp_path / "bats.csv")
    code = (
        "import json, sys\n"
        "from rig.cli import main\n"
        "code = main(sys.argv[1:])\n"
        "loaded = sorted(m for m in ('numba', 'scipy.stats') if m in sys.modules)\n"
        "print(json.dumps(loaded), file=sys.stderr)\n"
        "raise SystemExit(code)\n"
    )
    argv = ["model", "crosscheck", "--data", str(data), "--calibration", str(cal_path), "--json"]
    done = subprocess.run(
        [sys.executable, "-c", code, *argv], capture_output=True, text=True, check=True, timeout=300
    )
    assert json.loads(done.stderr.strip().splitlines()[-1]) == []
    fast.compiled()  # this process: the compiled kernel
    expected = [c.as_dict() for c in crosscheck_bats(cal, rows)]
    got = json.loads(done.stdout)
    assert [r["bat_id"] for r in got] == [r["bat_id"] for r in expected]
    for r, e in zip(got, expected, strict=True):
        assert r["flagged"] == e["flagged"]
        for key in ("predicted", "u_model", "z", "t_factor", "u_total"):
            assert abs(r[key] - e[key]) <= 1e-9, (r["bat_id"], key, r[key], e[key])
        assert np.max(np.abs(np.subtract(r["interval"], e["interval"]))) <= 1e-9
