"""`rig certify` with a model calibration: recorded in RunStarted, the calibrated cross-check in the
verdict and the certificate; without one an uncalibrated, unflagged prediction; old records still
report. The expected prediction is computed here with the single-solve path (rig.physics.predict_bat)
at the calibration's model constants and Eq. 5 written out, not with the cross-check's batch code.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.stats import t as student_t

from rig.certification import certify, history
from rig.cli import main
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import Model, RigConfig
from rig.core.errors import ConfigError
from rig.physics import DEFAULT_PARAMS as PAPER
from rig.physics import PivotedBat, predict_bat
from rig.population import write_population_csv
from rig.population.calfile import load_calibration
from rig.protocols.evaluate import run_calibration
from rig.protocols.procedure import Procedure
from rig.report.cert_plots import model_curve
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store
from rig.tui.live import LiveRun
from rig.tui.report import record_summary
from tests.population.test_calibrate import population

ROOT = Path(__file__).resolve().parents[2]
QUICK = (ROOT / "tests" / "tui" / "quick-bbcor.toml").read_text()
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml").model_copy(
    update={"id": "CAL-2200", "hoop_hz": 2200.0, "moi_kgm2": 0.19}
)
OLD_CROSS_CHECK = {  # the shape the fixed-tolerance check recorded before calibrations
    "predicted": 0.499,
    "measured": 0.462,
    "difference": -0.037,
    "tolerance": 0.05,
    "hoop_hz": 3600.0,
    "model": "pivoted bat with hoop mode (Eqs. 1-2)",
    "flagged": False,
    "note": "measured performance consistent with the hoop frequency",
}


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory with cal.json (12 synthetic bats, 1400-3000 Hz) and a procedure naming it relatively."""
    where = tmp_path_factory.mktemp("lab")
    data = write_population_csv(population(n=12, seed=5), where / "pop.csv")
    assert main(["model", "calibrate", "--data", str(data), "--output", str(where / "cal.json")]) == 0
    (where / "proc.toml").write_text(
        QUICK.replace("[procedure]\n", '[procedure]\ncalibration = "cal.json"\n')
    )
    return where


def _expected(cal_path: Path, q: float, moi: float) -> float:
    cal = load_calibration(cal_path)
    e_a = predict_bat(
        cal.model_params, 60.8, BAT.hoop_hz, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)
    ).e_a
    k = 0.145 * q * q / moi
    return e_a * (1.0 + k) + k + cal.parameters.get("offset", 0.0)


def test_a_calibrated_run_records_and_uses_the_calibration(
    lab: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, Procedure.load(lab / "proc.toml"), BAT, sim_config("ideal", bat=BAT))
        (started,) = store.entries(out.run_id, kinds=["RunStarted"])
        record = run_record(store, out.run_id)
    rec_cal = started.payload["calibration"]
    assert rec_cal["sha256"] == hashlib.sha256((lab / "cal.json").read_bytes()).hexdigest()
    assert Path(rec_cal["path"]) == lab / "cal.json" and rec_cal["named_by"] == "procedure"
    assert rec_cal["file"] == json.loads((lab / "cal.json").read_text())
    v, cc = record["verdict"], record["cross_check"]
    assert cc["calibrated"] is True and cc["measured"] == v["mean"]
    assert cc["predicted"] == pytest.approx(
        _expected(lab / "cal.json", v["impact_from_pivot_m"], v["moi_kgm2"]), abs=1e-7
    )
    cal = load_calibration(lab / "cal.json")
    assert cc["u_scatter"] == cal.scatter and cc["u_measured"] == v["u"] and cc["u_model"] > 0
    half = student_t.ppf(0.975, 12 - len(cal.parameters)) * math.sqrt(
        cc["u_model"] ** 2 + cal.scatter**2 + v["u"] ** 2
    )
    assert cc["interval"] == pytest.approx([cc["predicted"] - half, cc["predicted"] + half], rel=1e-12)
    assert (
        cc["flagged"] == (abs(v["mean"] - cc["predicted"]) > half) and cc["consistent"] is not cc["flagged"]
    )
    assert cc["coverage"] == 0.95 and not cc["extrapolated"]
    prov = cc["calibration"]["provenance"]
    assert prov == cal.provenance.model_dump() and cc["calibration"]["sha256"] == rec_cal["sha256"]
    md = render(record, "md", figures_dir=tmp_path / "figs", output=tmp_path / "cert.md")
    assert "prediction interval (95 %)" in md and f"{cc['interval'][0]:.4f} – {cc['interval'][1]:.4f}" in md
    assert rec_cal["sha256"] in md and prov["data_sha256"] in md and "12 bats, hoop" in md
    assert prov["created_utc"] in md and prov["software"] in md
    assert ("FLAGGED" in md) is cc["flagged"] and ("| result | consistent" in md) is not cc["flagged"]
    assert "<html" in render(record, "html", figures_dir=tmp_path / "figs")
    curve = model_curve(record, np.array([BAT.hoop_hz]))  # the certificate's figure: the calibrated model
    assert curve is not None and curve[0][0] == pytest.approx(cc["predicted"], abs=1e-6)
    live = LiveRun()
    with Store.open(tmp_path / "r.db") as store:
        for event in history(store, out.run_id):
            live.apply(event)
    assert live.prediction == pytest.approx(cc["predicted"])
    assert live.prediction_note == ("FLAGGED: out of line" if cc["flagged"] else "consistent (run's check)")
    assert f"predicts {cc['predicted']:.4f}" in record_summary(record)


def test_resume_uses_the_recorded_calibration_even_when_the_file_is_gone(lab: Path, tmp_path: Path) -> None:
    own = tmp_path / "lab"
    own.mkdir()
    for name in ("cal.json", "proc.toml"):
        (own / name).write_bytes((lab / name).read_bytes())
    good = sim_config("ideal", bat=BAT)
    bad = good.model_copy(update={"cannon_cycle_s": 1e308})  # overflows at the verdict: interrupted
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, Procedure.load(own / "proc.toml"), BAT, bad)
        assert out.status == "interrupted"
        sha = hashlib.sha256((own / "cal.json").read_bytes()).hexdigest()
        (own / "cal.json").unlink()
        procedure = Procedure.model_validate(
            store.entries(out.run_id, kinds=["RunStarted"])[0].payload["procedure"]
        )
        done = certify(store, procedure, BAT, good, run_id=out.run_id)
        assert done.status == "finished", done.reason
        cc = done.verdict.cross_check
        assert cc["calibrated"] is True and cc["calibration"]["sha256"] == sha
        assert store.verify().ok


def test_the_cli_resumes_with_the_recorded_calibration_when_the_file_is_gone(
    lab: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The resume's dry run rehearses what is left of the run: it does not load the calibration again."""
    from rig.cli import main

    own = tmp_path / "lab"
    own.mkdir()
    for name in ("cal.json", "proc.toml"):
        (own / name).write_bytes((lab / name).read_bytes())
    bad = sim_config("ideal", bat=BAT).model_copy(update={"cannon_cycle_s": 1e308})
    db = tmp_path / "r.db"
    with Store.open(db) as store:
        out = certify(store, Procedure.load(own / "proc.toml"), BAT, bad)
    assert out.status == "interrupted"
    (own / "cal.json").unlink()
    assert main(["certify", "--resume", out.run_id, "--sim", "ideal", "--db", str(db), "--dry-run"]) == 0
    assert main(["certify", "--resume", out.run_id, "--sim", "ideal", "--db", str(db)]) in (0, 1)
    with Store.open(db) as store:
        assert store.run(out.run_id).status == "finished"


def test_without_a_calibration_the_prediction_is_shown_and_not_judged(tmp_path: Path) -> None:
    with Store.open(tmp_path / "r.db") as store:
        out = certify(
            store,
            Procedure.load(ROOT / "tests" / "tui" / "quick-bbcor.toml"),
            BAT,
            sim_config("ideal", bat=BAT),
        )
        (started,) = store.entries(out.run_id, kinds=["RunStarted"])
        record = run_record(store, out.run_id)
    assert "calibration" not in started.payload
    cc, v = record["cross_check"], record["verdict"]
    assert cc["calibrated"] is False and cc["flagged"] is None and cc["interval"] is None
    assert cc["note"].startswith("uncalibrated: the model's absolute value is not validated")
    assert "the paper validates only normalized efficiency" in cc["note"]
    # the raw prediction: the paper's constants, Eq. 5 by hand, at the mean inbound speed of the hits
    from rig.physics import DEFAULT_PARAMS

    q, moi = v["impact_from_pivot_m"], v["moi_kgm2"]
    hits = [s for s in record["shots"] if s.get("purpose") == "valid" and s.get("valid")]
    v_in = sum(s["inbound_at_impact_m_s"] for s in hits) / len(hits)
    params = DEFAULT_PARAMS.model_copy(update={"m1": 0.145})
    e_a = predict_bat(params, v_in, BAT.hoop_hz, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)).e_a
    k = 0.145 * q * q / moi
    assert cc["predicted"] == pytest.approx(e_a * (1 + k) + k, rel=1e-6)
    md = render(record, "md", figures_dir=tmp_path)
    assert "predicted (uncalibrated)" in md and "not judged: no calibration" in md and "tolerance" not in md
    live = LiveRun()
    with Store.open(tmp_path / "r.db") as store:
        for event in history(store, out.run_id):
            live.apply(event)
    assert live.prediction_note == "uncalibrated: not judged"


def test_an_old_record_still_reports(tmp_path: Path) -> None:
    """The fixed-tolerance cross-check and a procedure without the new keys, as old records hold them."""
    with Store.open(tmp_path / "r.db") as store:
        out = certify(
            store,
            Procedure.load(ROOT / "tests" / "tui" / "quick-bbcor.toml"),
            BAT,
            sim_config("ideal", bat=BAT),
        )
        record = run_record(store, out.run_id)
    old: dict[str, Any] = copy.deepcopy(record)
    old["cross_check"] = dict(OLD_CROSS_CHECK)
    old["verdict"]["cross_check"] = dict(OLD_CROSS_CHECK)
    for key in ("calibration", "cross_check_coverage"):
        old["procedure"].pop(key)
    old["rig"].pop("model")
    Procedure.model_validate(old["procedure"])  # resume re-validates it
    RigConfig.model_validate(old["rig"])
    md = render(old, "md", figures_dir=tmp_path)
    assert "| tolerance | ± 0.05 |" in md and "| flagged | no |" in md and "0.4990" in md
    assert "Model at 3600.0 Hz predicts 0.4990" in record_summary(old)
    live = LiveRun()
    live.apply(ev.from_payload(ev.RUN_FINISHED, old["verdict"]))  # the old verdict as its log entry reads
    assert live.prediction == 0.499 and live.prediction_note == "consistent (run's check)"


def test_rig_config_names_the_calibration_relative_to_itself(lab: Path, tmp_path: Path) -> None:
    sub = tmp_path / "conf"
    sub.mkdir()
    (sub / "cal.json").write_bytes((lab / "cal.json").read_bytes())
    (sub / "rig.toml").write_text(
        (ROOT / "protocols" / "examples" / "rig.toml").read_text() + '\n[model]\ncalibration = "cal.json"\n'
    )
    config = RigConfig.load(sub / "rig.toml")
    assert config.model.calibration == str(sub / "cal.json")
    quick = Procedure.load(ROOT / "tests" / "tui" / "quick-bbcor.toml")
    recorded = run_calibration(quick, config)
    assert recorded is not None and recorded["named_by"] == "rig config"
    # the same file named by both is fine; two different files are refused
    assert run_calibration(
        Procedure.load(lab / "proc.toml").model_copy(update={"calibration": str(sub / "cal.json")}), config
    )
    with pytest.raises(ConfigError, match="name one"):
        run_calibration(Procedure.load(lab / "proc.toml"), config)


@pytest.mark.parametrize(
    ("how", "cause"),
    [
        ("missing", "no such file"),
        ("metric", "a bbcor calibration; the procedure certifies besr"),
        ("damaged", "covariance must be"),
    ],
)
def test_a_bad_calibration_stops_the_run_before_anything_is_recorded(
    how: str, cause: str, lab: Path, tmp_path: Path
) -> None:
    cal = tmp_path / "cal.json"
    if how == "damaged":
        broken = json.loads((lab / "cal.json").read_text())
        broken["covariance"] = broken["covariance"][:1]
        cal.write_text(json.dumps(broken))
    elif how != "missing":
        cal.write_bytes((lab / "cal.json").read_bytes())
    proc = Procedure.load("besr" if how == "metric" else ROOT / "tests" / "tui" / "quick-bbcor.toml")
    config = sim_config("ideal", bat=BAT).model_copy(update={"model": Model(calibration=str(cal))})
    with Store.open(tmp_path / "r.db") as store:
        with pytest.raises(ConfigError, match=cause):
            certify(store, proc, BAT, config)
        assert store.runs() == []


def test_an_unusable_recorded_calibration_leaves_the_verdict_uncalibrated(lab: Path) -> None:
    from rig.protocols.evaluate import cross_check

    quick = Procedure.load(lab / "proc.toml")
    recorded = run_calibration(quick, sim_config("ideal", bat=BAT))
    assert recorded is not None
    q = BAT.impact_from_pivot_m(6.5)
    good = cross_check(quick, BAT, 60.8, q, 0.19, 0.5, 0.004, recorded)
    assert good["calibrated"] is True
    damaged = copy.deepcopy(recorded)
    damaged["file"]["covariance"] = [[1.0]]
    cc = cross_check(quick, BAT, 60.8, q, 0.19, 0.5, 0.004, damaged)
    assert cc["calibrated"] is False and cc["flagged"] is None
    assert cc["note"].startswith("recorded calibration not usable (") and "covariance must be" in cc["note"]


def test_cli_certify_report_and_verify_with_a_calibration(
    lab: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bat = tmp_path / "bat.toml"
    bat.write_text(
        '[bat]\nid = "CLI-2200"\nlength_in = 33.0\nweight_oz = 30.0\nbarrel = "aluminium"\n'
        "hoop_hz = 2200.0\nmoi_kgm2 = 0.19\nbalance_point_in = 22.0\n"
    )
    db = str(tmp_path / "r.db")
    argv = ["certify", "--procedure", str(lab / "proc.toml"), "--bat", str(bat), "--sim", "ideal", "--db", db]
    assert main([*argv, "--json"]) in (0, 1)
    record = json.loads(capsys.readouterr().out)
    cc = record["cross_check"]
    assert cc["calibrated"] is True and cc["interval"][0] < cc["predicted"] < cc["interval"][1]
    assert cc["calibration"]["sha256"] == hashlib.sha256((lab / "cal.json").read_bytes()).hexdigest()
    assert main(["report", "last", "--db", db, "--format", "md", "--figures", str(tmp_path / "f")]) == 0
    md = capsys.readouterr().out
    assert "prediction interval (95 %)" in md and cc["calibration"]["sha256"] in md
    assert main(["verify", "--db", db]) == 0


def test_the_console_preview_uses_the_calibration_the_verdict_will(lab: Path) -> None:
    """The console's prediction before the verdict (rig.tui.jobs.predict) is the calibrated one when
    a calibration is named (it showed the paper's constants, 0.06-0.1 off, before)."""
    from rig.tui.jobs import predict
    from rig.tui.rigs import RunJob

    procedure = Procedure.load(lab / "proc.toml")
    job = RunJob(procedure, BAT, sim_config("ideal"), "sim")
    value, note = predict(job, 0.19, 6.5)
    q = BAT.impact_from_pivot_m(6.5)
    assert value == pytest.approx(_expected(lab / "cal.json", q, 0.19), abs=1e-6)
    assert note.startswith("calibrated 0.")  # its interval, on one line of the panel at 80x24
    plain = RunJob(
        Procedure.load(ROOT / "tests" / "tui" / "quick-bbcor.toml"), BAT, sim_config("ideal"), "sim"
    )
    value, note = predict(plain, 0.19, 6.5)
    assert note.startswith("uncalibrated") and value is not None


def test_a_run_with_another_ball_law_than_the_calibrations_is_not_judged_by_it(lab: Path) -> None:
    """The calibration's barrel was fitted with the paper's ball: a run that names another ball law
    gets the uncalibrated prediction made with its own law, and no flag."""
    from rig.protocols.verdict import cross_check

    procedure = Procedure.model_validate(
        {**Procedure.load("bbcor").model_dump(), "calibration": str(lab / "cal.json")}
    )
    cal = run_calibration(procedure, sim_config("ideal"))
    assert cal is not None
    q, moi, v_in = 0.5, 0.19, 60.8
    same = cross_check(procedure, BAT, v_in, q, moi, 0.48, 0.002, cal)
    assert same["calibrated"] is True
    law = {"a": 0.31, "b": 0.27}  # not the paper's exponents
    other = cross_check(procedure, BAT, v_in, q, moi, 0.48, 0.002, cal, law)
    assert other["calibrated"] is False and other["flagged"] is None
    assert "the calibration was made with the paper's ball, not this run's" in other["note"]
    params = PAPER.model_copy(update={"m1": procedure.ball.mass_kg, **law})
    e_a = predict_bat(params, v_in, BAT.hoop_hz, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)).e_a
    k = params.m1 * q * q / moi
    assert other["predicted"] == pytest.approx(e_a * (1 + k) + k, abs=1e-12)  # BBCOR written out
