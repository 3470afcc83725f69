"""`rig model calibrate --metric` for a BPF and a USA Softball BBS, and the calibrated cross-check of a
certification of that metric (issue 25).

The population's rows are the simulated bats' truth (the scene's own collision at the standard's
speed and ball, at the scanned location of maximum) plus a little noise, as studies/population/lab.py
makes them: certifying a dozen bats would take minutes. One more bat is then certified on the
simulated rig through the real drivers with the calibration, and its calibrated prediction is held
against that bat's simulated truth, computed here apart from the model (the scene's collision)."""

from __future__ import annotations

import contextlib
import io
import json
import random
from pathlib import Path
from typing import Any

import pytest

from rig.cli import main
from rig.core.bat import BatSpec
from rig.physics import rigid_cor
from rig.population.dataset import PopulationBat, write_population_csv
from rig.population.store_source import RunConditions, bats_from_store
from rig.session import scene_with_bat
from rig.simulators.scene import Scene
from rig.simulators.truth import true_metric
from rig.store import Store
from tests.protocols.test_bpf_lab import LOT, no_drag_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "simulators" / "scenes"
MPH = 0.44704
SCAN_IN = tuple(5.0 + 0.5 * i for i in range(6))  # the procedures' scan, 5.0-7.5 in
# metric: (procedure, scene, ball class, length in, ball mass kg, the standard's speed m/s)
CASES = {
    "usssa_bpf": ("usssa-bpf", "lab", None, 33.0, 0.145, 26.82),
    "fastpitch_bpf": ("fastpitch-bpf", "softball", "47/375", 34.0, 0.187, 26.82),
    "usas_bbs_2012": ("softball-bbs", "softball", "44/375", 34.0, 0.187, 105.0 * MPH),
}
# a BPF's ball lot: (id, nominal COR, the built-in ball-cor test of its balls), as test_bpf_lab's
LOTS = {"usssa_bpf": ("BASE1", 0.52, "ball-cor"), "fastpitch_bpf": ("FAST1", 0.47, "ball-cor-fastpitch")}
HOOPS = (1200.0, 1350.0, 1500.0, 1650.0, 1800.0, 1950.0, 2100.0, 2250.0, 2400.0, 2600.0)  # 1400 Hz span


def cli(*args: str) -> tuple[int, str, str]:
    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        code = main(list(args))
    return int(code or 0), out.getvalue(), err.getvalue()


def bat_file(folder: Path, bat_id: str, length_in: float, hoop_hz: float, moi: float) -> Path:
    path = folder / f"{bat_id}.toml"
    path.write_text(
        f'[bat]\nid = "{bat_id}"\nlength_in = {length_in}\nweight_oz = {length_in - 5.0}\n'
        f'barrel = "aluminium"\nhoop_hz = {hoop_hz}\nbalance_point_in = 21.0\n'
        f"[simulated]\nmoi_kgm2 = {moi}\n",
        encoding="utf-8",
    )
    return path


def truth_scene(scene: str, ball_class: str | None, bat: Path) -> Scene:
    base = Scene.load(scene if scene.endswith(".toml") else SCENES / f"{scene}.toml")
    return scene_with_bat(base.with_ball_class(ball_class) if ball_class else base, BatSpec.load(bat))


def population(folder: Path, metric: str, scene: str) -> Path:
    """Ten bats spanning 1400 Hz: each its true BBCOR at the standard's speed + N(0, 0.002)."""
    _, _, ball_class, length, _, speed = CASES[metric]
    draw = random.Random(25)
    rows = []
    for i, hoop in enumerate(HOOPS):
        moi = 0.165 + 0.003 * (i % 5)
        path = bat_file(folder, f"POP-{i:02d}", length, hoop, moi)
        truth = true_metric(truth_scene(scene, ball_class, path), SCAN_IN, "bbcor", speed)
        rows.append(
            PopulationBat(
                bat_id=f"POP-{i:02d}",
                barrel="aluminium",
                hoop_hz=hoop,
                length_in=length,
                moi_kgm2=moi,
                location_in=truth.location_in,
                bbcor=truth.value + draw.gauss(0.0, 0.002),
                source=f"simulated ({scene} scene truth + noise)",
            )
        )
    return write_population_csv(rows, folder / f"{metric}.csv")


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Per metric: its calibration, and one more bat certified with it (record, store, truth)."""
    folder = tmp_path_factory.mktemp("calmetric")
    out: dict[str, Any] = {"folder": folder}
    for metric, (procedure, name, ball_class, length, mass, speed) in CASES.items():
        # still air, as test_bpf_lab's: a 60 mph softball's rebound off the scan's far end then reaches
        # the gates
        scene = str(no_drag_scene(folder, name))
        data = population(folder, metric, scene)
        cal = folder / f"{metric}.json"
        argv = ["model", "calibrate", "--data", str(data), "--metric", metric, "--output", str(cal)]
        code, _, err = cli(*argv, "--ball-mass-kg", str(mass), "--no-progress")
        assert code == 0, err
        db = str(folder / f"{metric}.db")
        bat = bat_file(folder, f"ONE-{metric}", length, 1500.0, 0.17)
        extra: list[str] = []
        if metric in LOTS:
            lot, cor, test = LOTS[metric]
            (folder / f"{lot}.toml").write_text(LOT.format(id=lot, model=metric, cor=cor), encoding="utf-8")
            assert cli("balls", "register", str(folder / f"{lot}.toml"), "--db", db)[0] == 0
            code, _, err = cli("balls", "test", "--procedure", test, "--lot", lot, "--sim", scene, "--db", db)
            assert code == 0, err
            extra = ["--ball-lot", lot]
        certify = ["certify", "--procedure", procedure, "--bat", str(bat), "--sim", scene, "--db", db]
        code, _, err = cli(*certify, *extra, "--calibration", str(cal))
        assert code in (0, 1), err  # a verdict, PASS or FAIL
        record = json.loads(cli("report", "last", "--db", db, "--format", "json")[1])
        sim = truth_scene(scene, ball_class, bat)
        truth = true_metric(sim, SCAN_IN, "bbcor", speed)
        out[metric] = {
            "cal": cal,
            "file": json.loads(cal.read_text(encoding="utf-8")),
            "db": db,
            "bat": bat,
            "record": record,
            "md": cli("report", "last", "--db", db, "--format", "md")[1],
            "true_bbcor": truth.value,
            "true_location_in": truth.location_in,
            "sim": sim,
            "speed": speed,
        }
    return out


def true_value(case: dict[str, Any], metric: str, q_m: float) -> float:
    """The simulated bat's true metric, with formulas written here: BPF = BBCOR / the ball's COR on a
    rigid wall at 60 mph; USA Softball BBS (2012) = 25 mph e_A + V_bat (1 + e_A), the bat turning about
    6 in from the knob at 80 mph 6 in from the barrel end."""
    sim = case["sim"]
    if metric in LOTS:
        return float(case["true_bbcor"] / rigid_cor(sim.ball, 60 * MPH))
    k = sim.ball.m1 * q_m**2 / sim.bat.moi_kgm2
    e_a = (case["true_bbcor"] - k) / (1 + k)
    v_bat = 80 * MPH * q_m / (sim.bat.length_m - 12 * 0.0254)
    return 25 * MPH * e_a + v_bat * (1 + e_a)


@pytest.mark.parametrize("metric", list(CASES))
def test_the_calibration_records_its_metric_speed_ball_and_what_it_fitted(
    runs: dict[str, Any], metric: str
) -> None:
    f = runs[metric]["file"]
    assert f["metric"] == metric and f["fitted"] == "bbcor"
    assert f["speed_m_s"] == pytest.approx(CASES[metric][5], abs=0.005)  # the standard's: 60 mph
    assert f["model_params"]["m1"] == pytest.approx(CASES[metric][4])
    assert f["provenance"]["n_bats"] == len(HOOPS) and f["loo_rmse"] < 0.02


@pytest.mark.parametrize("metric", list(CASES))
def test_a_certification_with_the_calibration_predicts_the_simulated_truth_within_its_interval(
    runs: dict[str, Any], metric: str
) -> None:
    case = runs[metric]
    verdict, cc = case["record"]["verdict"], case["record"]["cross_check"]
    assert cc["calibrated"] is True and cc["metric"] == metric, cc.get("note")
    assert cc["consistent"] is (not cc["flagged"])
    low, high = cc["interval"]
    truth = true_value(case, metric, verdict["impact_from_pivot_m"])
    assert low <= truth <= high, (low, truth, high)
    assert low <= cc["predicted"] <= high and high - low < (0.15 if metric in LOTS else 4.0)
    if metric in LOTS:  # the ball COR's u, counted once, and only in a BPF
        assert cc["u_ball_cor"] > 0.0
    else:
        assert cc["u_ball_cor"] == 0.0
    assert "calibrated (" in cc["model"] and "interval" in case["md"].lower()


def test_the_store_gives_the_bpf_runs_bbcor_and_their_speed_and_ball(runs: dict[str, Any]) -> None:
    case = runs["usssa_bpf"]
    found: list[RunConditions] = []
    with Store.open(case["db"], create=False) as store:
        bats, _ = bats_from_store(store, "usssa_bpf", found)
        none, notes = bats_from_store(store, "usas_bbs_2012", [])
    assert [b.bat_id for b in bats] == ["ONE-usssa_bpf"] and bats[0].bbcor is not None
    assert abs(bats[0].bbcor - case["true_bbcor"]) < 0.02
    assert found == [RunConditions(26.82, 0.145)]
    assert none == [] and any("no certified usas_bbs_2012 run" in n for n in notes)


def test_a_calibration_of_another_metric_speed_or_ball_is_refused_in_one_line(runs: dict[str, Any]) -> None:
    folder: Path = runs["folder"]
    case = runs["usas_bbs_2012"]
    bat, db = str(case["bat"]), str(folder / "refused.db")
    base = ["certify", "--procedure", "softball-bbs", "--bat", bat, "--sim", "softball", "--db", db]
    # another metric: the BPF's calibration on a softball BBS certification
    code, _, err = cli(*base, "--calibration", str(runs["usssa_bpf"]["cal"]))
    assert code == 2 and "a usssa_bpf calibration; the procedure certifies usas_bbs_2012" in err
    # another speed: the 2012 calibration as if made at the 2004 edition's 110 mph
    data = dict(case["file"], speed_m_s=110 * MPH)
    other = folder / "other-speed.json"
    other.write_text(json.dumps(data), encoding="utf-8")
    code, _, err = cli(*base, "--calibration", str(other))
    assert code == 2 and "calibrated at 49.1744 m/s; the procedure shoots at 46.9392 m/s" in err
    # another ball: a baseball calibration for softballs
    data = dict(case["file"], model_params=dict(case["file"]["model_params"], m1=0.145))
    ball = folder / "other-ball.json"
    ball.write_text(json.dumps(data), encoding="utf-8")
    code, _, err = cli(*base, "--calibration", str(ball))
    assert code == 2 and "calibrated with 0.145 kg balls; the procedure fires 0.187 kg balls" in err
    for message in (err,):
        assert message.count("\n") == 1
    assert not Path(db).exists() or not Store.open(db, create=False).runs()


def test_a_bpf_or_softball_calibration_from_data_alone_needs_the_ball_mass(runs: dict[str, Any]) -> None:
    folder: Path = runs["folder"]
    data = folder / "usssa_bpf.csv"
    code, _, err = cli(
        "model", "calibrate", "--data", str(data), "--metric", "usssa_bpf", "--output", str(folder / "x.json")
    )
    assert code == 2 and "needs --ball-mass-kg" in err and err.count("\n") == 1
    code, _, err = cli(
        "model", "calibrate", "--data", str(data), "--output", str(folder / "x.json"), "--ball-mass-kg", "0.2"
    )
    assert code == 2 and "--ball-mass-kg is for a BPF or USA Softball BBS" in err and err.count("\n") == 1
    code, _, err = cli(
        "model", "crosscheck", "--data", str(data), "--calibration", str(runs["usssa_bpf"]["cal"])
    )
    assert code == 2 and "its cross-check is made in rig certify" in err and err.count("\n") == 1


def test_the_store_runs_feed_the_calibration_with_their_speed_and_ball(runs: dict[str, Any]) -> None:
    """--db with --data: the store's certified BPF run joins the rows, and its recorded speed and
    ball mass are the calibration's (no --ball-mass-kg)."""
    folder: Path = runs["folder"]
    case = runs["usssa_bpf"]
    out = folder / "with-store.json"
    code, _, err = cli(
        "model", "calibrate", "--data", str(folder / "usssa_bpf.csv"), "--db", case["db"],
        "--metric", "usssa_bpf", "--output", str(out), "--no-progress",
    )  # fmt: skip
    assert code == 0, err
    f = json.loads(out.read_text(encoding="utf-8"))
    assert f["provenance"]["n_bats"] == len(HOOPS) + 1 and "ONE-usssa_bpf" in [b["bat_id"] for b in f["bats"]]
    assert f["speed_m_s"] == 26.82 and f["model_params"]["m1"] == 0.145 and f["fitted"] == "bbcor"
