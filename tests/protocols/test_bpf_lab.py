"""BPF certified end to end on the simulated lab through the real drivers (`rig certify --sim`), as a lab
does it: the lot registered, its ball COR measured on the rigid plate, then the bat. Each BPF is
recomputed from the raw record (gate ticks of the bat's hits and of the lot's ball-cor test) with
formulas written here, its u checked for the ball COR's correlated term, and the certified value
compared with the simulated truth."""

from __future__ import annotations

import contextlib
import io
import json
import math
import shlex
import signal
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from rig.cli import main
from rig.core.bat import BatSpec
from rig.physics import rigid_cor
from rig.session import scene_with_bat
from rig.simulators.scene import Scene
from rig.simulators.truth import true_metric
from rig.store import Store
from tests.e2e.procs import burners, certify_child, count, wait_count
from tests.protocols.wire import check_fires

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "simulators" / "scenes"
MPH = 0.44704
AIR = (("temperature_c", "temp_c"), ("humidity_pct", "rh_pct"))  # a shot's air, the lot's nominal
LOT = """\
[lot]
id = "{id}"
maker = "Acme"
model = "{model}"
balls = 60
[lot.specification]
nominal_cor = {cor}
cor_tolerance = 0.03
[lot.conditioning]
temperature_c = 21.0
humidity_pct = 50.0
days = 14
"""
# (procedure, scene, bat, lot, nominal COR, the built-in ball-cor test of the procedure's balls)
CASES = {
    "usssa-bpf": ("lab", "sample-bat.toml", "BASE1", 0.52, "ball-cor"),
    "fastpitch-bpf": ("softball", "softball-bat.toml", "FAST1", 0.47, "ball-cor-fastpitch"),
}


def cli(*args: str) -> tuple[int, str, str]:
    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        code = main(list(args))
    return int(code or 0), out.getvalue(), err.getvalue()


def no_drag_scene(folder: Path, name: str) -> Path:
    """The built-in scene with its drag effect off: every speed is then the gates' own."""
    text = (SCENES / f"{name}.toml").read_text(encoding="utf-8")
    path = folder / f"{name}-still-air.toml"
    path.write_text(text.replace('kind = "drag"', 'kind = "drag"\nenabled = false'), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Per case: the ball-cor test's record and the BPF run's record, certificate and exit status."""
    folder = tmp_path_factory.mktemp("bpf-lab")
    db = str(folder / "records.db")
    out: dict[str, Any] = {"db": db, "folder": folder}
    for name, (scene_name, bat, lot, cor, ball) in CASES.items():
        scene = no_drag_scene(folder, scene_name)
        (folder / f"{lot}.toml").write_text(LOT.format(id=lot, model=name, cor=cor), encoding="utf-8")
        assert cli("balls", "register", str(folder / f"{lot}.toml"), "--db", db)[0] == 0
        code, _, err = cli(
            "balls", "test", "--procedure", ball, "--lot", lot, "--sim", str(scene), "--db", db
        )
        assert code == 0, err
        ball_run = json.loads(cli("report", "last", "--db", db, "--format", "json")[1])
        bat_file = str(ROOT / "protocols" / "examples" / bat)
        argv = ["certify", "--procedure", name, "--bat", bat_file, "--sim", str(scene), "--db", db]
        code, _, err = cli(*argv, "--ball-lot", lot)
        record = json.loads(cli("report", "last", "--db", db, "--format", "json")[1])
        md = cli("report", "last", "--db", db, "--format", "md")[1]
        html = folder / f"{name}.html"
        assert cli("report", "last", "--db", db, "--format", "html", "--output", str(html))[0] == 0
        out[name] = {
            "code": code,
            "err": err,
            "ball_run": ball_run,
            "record": record,
            "md": md,
            "html": html.read_text(encoding="utf-8"),
            "scene": scene,
            "bat": bat_file,
        }
    return out


def gate_speeds(raw: dict[str, Any]) -> tuple[float, float]:
    """(inbound, rebound) m/s over the two gates nearest the impact, from the latched ticks: the
    inbound crossings come first (gate 1, 2, 3), the rebound's after them (nearest gate first)."""
    tick_s = raw["gate_config"]["tick_ns"] * 1e-9
    x = raw["gate_positions_m"]
    crossings = raw["crossings"]
    inbound = {c["gate"]: c["tick"] for c in crossings[: len(x)]}
    rebound = {c["gate"]: c["tick"] for c in crossings[len(x) :]}
    near, next_ = len(x), len(x) - 1
    span = x[next_ - 1] - x[near - 1]
    return span / ((inbound[near] - inbound[next_]) * tick_s), span / (
        (rebound[next_] - rebound[near]) * tick_s
    )


def lot_cor(ball_run: dict[str, Any]) -> float:
    """The lot's COR: each ball's mean COR over its valid hits, then the mean over the balls."""
    by_ball: dict[str, list[float]] = {}
    for s in ball_run["shots"]:
        if s.get("valid"):
            v_in, v_out = gate_speeds(s["raw"])
            by_ball.setdefault(s["raw"]["ball"], []).append(v_out / v_in)
    return sum(sum(c) / len(c) for c in by_ball.values()) / len(by_ball)


@pytest.mark.parametrize("name", list(CASES))
def test_bpf_recomputes_from_the_gate_ticks_and_the_lots_ball_test(lab: dict[str, Any], name: str) -> None:
    case = lab[name]
    record, verdict = case["record"], case["record"]["verdict"]
    assert record["status"] == "finished", case["err"]
    assert case["code"] == (0 if verdict["verdict"] == "PASS" else 1)
    cor = lot_cor(case["ball_run"])
    assert record["ball"]["wall_cor"] == pytest.approx(cor, rel=1e-9)
    assert record["ball"]["wall_cor_run"] == case["ball_run"]["run_id"]
    assert record["ball"]["wall_cor_u"] == case["ball_run"]["lot_result"]["u"]
    m_ball = record["procedure"]["ball"]["mass_kg"]
    moi = record["moi"]["moi_kgm2"]
    recomputed: dict[int, float] = {}
    for s in record["shots"]:
        if s.get("metric") is None:
            continue
        v_in, v_out = gate_speeds(s["raw"])
        assert abs(v_in - 60 * MPH) < 1.5 * 0.447
        k = m_ball * s["raw"]["impact_from_pivot_m"] ** 2 / moi
        bbcor = v_out / v_in * (1 + k) + k
        recomputed[s["index"]] = bbcor / cor
        assert (
            s["metric"]
            == s["metrics"][record["procedure"]["standard"]]
            == pytest.approx(bbcor / cor, rel=1e-9)
        )
    hits = verdict["hits"]
    assert len(hits) == verdict["n_hits"] == 6
    assert verdict["mean"] == pytest.approx(sum(hits) / len(hits), rel=1e-12)
    # the averaged hits: each its BBCOR moved to a new ball (wear measured on the lot: -g wear n, n its
    # ball's hits before) and to the nominal air (the assumed sensitivities s: -g s.(T - 21, RH - 50)),
    # over the lot's COR moved to a new ball (mean hit count 1 + wear ...) and to the nominal air too
    averaged = [
        s
        for s in record["shots"]
        if s.get("valid") and s["purpose"] == "valid" and s["location_in"] == verdict["location_in"]
    ]
    result, ball, terms = case["ball_run"]["lot_result"], verdict["ball"], record["ball"]
    wear, g = result["wear_per_hit"], ball["g"]
    slope = (terms["cor_per_c"], terms["cor_per_pct_rh"])
    cor_air = -sum(
        k * (terms[f"wall_cor_{n}"] - terms[n]) for k, n in zip(slope, ("temp_c", "rh_pct"), strict=True)
    )
    cor_new = cor - wear * (result["mean_hit"] - 1) + cor_air
    assert verdict["bpf"]["ball_cor"] == pytest.approx(cor_new, rel=1e-9)
    assert len(averaged) == 6 and ball["corrections"] == pytest.approx(
        [-g * wear * s["raw"]["ball_hits"] for s in averaged], rel=1e-9, abs=1e-15
    )
    air = [
        -g * sum(k * (s[key] - terms[nom]) for k, (key, nom) in zip(slope, AIR, strict=True))
        for s in averaged
    ]
    assert verdict["bpf"]["air_corrections"] == pytest.approx(air, rel=1e-9)
    for s, h, c, a in zip(averaged, hits, ball["corrections"], air, strict=True):
        assert h == pytest.approx((recomputed[s["index"]] * cor + c + a) / cor_new, rel=1e-9)
    cor = cor_new
    parts = verdict["bpf"]
    assert parts["bbcor_mean"] == pytest.approx(verdict["mean"] * cor, rel=1e-9)
    # the ball COR's own u (its test's) enters the mean once: BPF u(COR) / COR, not divided by sqrt(n)
    bpf_mean, terms = verdict["mean"], record["ball"]
    u_test = case["ball_run"]["lot_result"]["u"]
    assert parts["u_from_ball_cor"] == pytest.approx(bpf_mean * u_test / cor, rel=1e-9)
    own = math.sqrt(parts["u_bbcor_hits"] ** 2 + ball["u_spread"] ** 2 + ball["u_ratio"] ** 2)
    assert parts["u_from_bbcor"] == pytest.approx(own / cor, rel=1e-9)
    # one sensitivity moves the hits (g s d_hits) and the COR (s d_cor): BPF by s (g d_hits - BPF d_cor)
    # / COR; both moved by the assumed s, what is left is its u's share, with the air readings' own u
    assert not terms["conditions_measured"]  # assumed: corrected, their u per C and per % RH budgeted
    d_hits = [sum(s[key] - terms[nom] for s in averaged) / 6 for key, nom in AIR]
    d_cor = [terms["wall_cor_temp_c"] - terms["temp_c"], terms["wall_cor_rh_pct"] - terms["rh_pct"]]
    sens = [terms["cor_per_c_u"], terms["cor_per_pct_rh_u"]]
    readings = math.hypot(slope[0] * terms["sensor_u_c"], slope[1] * terms["sensor_u_pct"])
    u_air = math.hypot(
        *[s * (g * h - bpf_mean * c) / cor for s, h, c in zip(sens, d_hits, d_cor, strict=True)],
        readings * math.hypot(g, bpf_mean) / cor,
    )
    mean_hits = sum(s["raw"]["ball_hits"] for s in averaged) / 6
    u_wear = abs(g * mean_hits - bpf_mean * (result["mean_hit"] - 1)) * terms["wear_per_hit_u"] / cor
    assert parts["u_shared_air"] == pytest.approx(u_air, rel=1e-9)
    assert parts["u_shared_wear"] == pytest.approx(u_wear, rel=1e-9, abs=1e-15)
    assert verdict["u"] == pytest.approx(
        math.sqrt(parts["u_from_bbcor"] ** 2 + parts["u_from_ball_cor"] ** 2 + u_air**2 + u_wear**2), rel=1e-9
    )
    assert verdict["U"] == pytest.approx(2 * verdict["u"], rel=1e-12)
    limit = {"usssa-bpf": 1.15, "fastpitch-bpf": 1.20}[name]
    assert verdict["limit"] == limit
    assert verdict["verdict"] == ("PASS" if verdict["mean"] + verdict["U"] <= limit else "FAIL")


@pytest.mark.parametrize("name", list(CASES))
def test_the_certified_bpf_is_the_simulated_bats_within_its_uncertainty(
    lab: dict[str, Any], name: str
) -> None:
    """The truth: the bat's BBCOR at its scanned maximum, 60 mph, a new ball of the lot's nominal
    ball, over that ball's COR on the rigid plate at 60 mph (scene and bat, no measurement chain)."""
    case = lab[name]
    verdict = case["record"]["verdict"]
    ball_class = case["record"]["procedure"]["ball"].get("ball_class")
    scene = scene_with_bat(Scene.load(case["scene"]).with_ball_class(ball_class), BatSpec.load(case["bat"]))
    locations = tuple(case["record"]["procedure"]["scan"]["from_in"] + 0.5 * i for i in range(6))
    truth = true_metric(scene, locations, "bbcor", 60 * MPH)
    true_bpf = truth.value / rigid_cor(scene.ball, 60 * MPH)
    # the balls wear (c1 +0.1 % a hit) in the bat's hits and in the lot's test alike: what is left
    # is within the measurement's U
    assert abs(verdict["mean"] - true_bpf) <= verdict["U"], (verdict["mean"], true_bpf, verdict["U"])
    assert abs(verdict["location_in"] - truth.location_in) <= 0.5


def test_the_certificates_show_the_basis_the_ball_cor_and_bpf(lab: dict[str, Any]) -> None:
    for name, lot in (("usssa-bpf", "BASE1"), ("fastpitch-bpf", "FAST1")):
        md, html = lab[name]["md"], lab[name]["html"]
        for text in (md, html):
            assert "Bat performance factor" in text and f"of lot {lot}" in text
            assert (
                "pivoted" in text and "ASTM F1890-23" in text and "not unconstrained (ASTM F2219-23)" in text
            )
            assert "BPF = BBCOR / ball COR" in text
            # the COR as measured, what moved it to the nominal ball, the shared terms; no stale claim
            assert "ball COR measured (rigid flat wall, 60 mph)" in text and "(the divisor)" in text
            assert "u shared: the air" in text and "not corrected for wear" not in text
        assert "| ball class | 47/375 |" in lab["fastpitch-bpf"]["md"]
        # the ball's terms and corrections are in BBCOR, the BPF's numerator, and said so
        assert "standard u (BBCOR (pivoted))" in md and "| BBCOR (pivoted) corrected |" in md
        assert "the ball's terms (in BBCOR, u = " in md


def test_a_bpf_without_a_lot_is_refused_in_one_line_and_records_nothing(lab: dict[str, Any]) -> None:
    before = cli("runs", "--db", lab["db"], "--json")[1]
    bat = str(ROOT / "protocols" / "examples" / "sample-bat.toml")
    code, _, err = cli("certify", "--procedure", "usssa-bpf", "--bat", bat, "--sim", "lab", "--db", lab["db"])
    assert code == 2 and "--ball-lot" in err and "ball-cor" in err and err.count("\n") == 1
    assert cli("runs", "--db", lab["db"], "--json")[1] == before


@pytest.mark.parametrize(("name", "lot"), [("fastpitch-bpf", "BASE1"), ("usssa-bpf", "FAST1")])
def test_a_lot_tested_with_other_balls_is_refused_in_one_line_and_records_nothing(
    lab: dict[str, Any], name: str, lot: str
) -> None:
    """BASE1's ball-cor test fired baseballs, FAST1's 47/375 softballs: neither COR is the other's."""
    before = cli("runs", "--db", lab["db"], "--json")[1]
    scene, bat = lab[name]["scene"], lab[name]["bat"]
    argv = ["certify", "--procedure", name, "--bat", bat, "--sim", str(scene), "--db", lab["db"]]
    code, _, err = cli(*argv, "--ball-lot", lot)
    assert code == 2 and err.count("\n") == 1, err
    assert f"lot {lot}'s ball-cor test" in err and "47/375" in err
    assert {"fastpitch-bpf": "--procedure ball-cor-fastpitch)", "usssa-bpf": "--procedure ball-cor)"}[
        name
    ] in err
    assert cli("runs", "--db", lab["db"], "--json")[1] == before


def test_a_bpf_run_stopped_by_sigint_resumes_at_its_positions_and_verifies(lab: dict[str, Any]) -> None:
    """Ctrl-C (SIGINT) to a `rig certify` child mid-run (after its 7th fire: past the scan), then
    `rig certify --resume`: the run finishes, every shot fired once with the stage at its recorded
    location (the FIRE and MOVE commands on the wire), each BPF is its BBCOR over the lot's COR the
    run recorded at its start, and the record verifies."""
    db, case = Path(lab["db"]), lab["fastpitch-bpf"]
    fired = count(db, "ShotFired")
    with burners():
        args = ["--procedure", "fastpitch-bpf", "--bat", case["bat"], "--sim", str(case["scene"])]
        child = certify_child(db, *args, "--ball-lot", "FAST1")
        try:
            wait_count(db, "ShotFired", fired + 7, child)
            child.send_signal(signal.SIGINT)
            _, err = child.communicate(timeout=120)
        finally:
            if child.poll() is None:
                child.kill()
    assert child.returncode == 3 and "rig certify --resume " in err, err
    run_id = err.split("rig certify --resume ")[1].split()[0]
    printed = shlex.split(err.split("resume with: ")[1].splitlines()[0])
    assert printed[printed.index("--bat") + 1] == case["bat"]  # the command to resume names the bat's file
    # the record keeps the bat, not the file's [simulated] truth (MOI 0.17): the simulated rig needs
    # the file again, else the simulated bat is another and every recoil disagrees with the MOI measured
    resume = ["certify", "--resume", run_id, "--sim", str(case["scene"]), "--db", lab["db"]]
    other = ROOT / "protocols" / "examples" / "sample-bat.toml"
    code, _, err = cli(*resume, "--bat", str(other))
    assert code == 2 and "not the bat the run recorded (SAMPLE-SB-34)" in err and err.count("\n") == 1
    code, _, err = cli(*resume, "--bat", case["bat"])
    assert code in (0, 1), err
    with Store.open(db) as store:
        entries = store.entries(run_id)
        assert store.run(run_id).status == "finished"
    kinds = Counter(e.kind for e in entries)
    assert kinds["RunInterrupted"] == 1 and kinds["RunResumed"] == 1 and kinds["RunFinished"] == 1
    assert "SIGINT" in next(e.payload["reason"] for e in entries if e.kind == "RunInterrupted")
    per_shot = check_fires(entries)
    assert per_shot and all(n == 1 for n in per_shot.values())  # no shot fired twice
    record = json.loads(cli("report", run_id, "--db", lab["db"], "--format", "json")[1])
    cor = record["ball"]["wall_cor"]
    assert cor == pytest.approx(lot_cor(case["ball_run"]), rel=1e-9)  # the lot's, as recorded at the start
    for s in record["shots"]:
        if s.get("metric") is not None:
            assert s["metric"] == pytest.approx(s["metrics"]["bbcor"] / cor, rel=1e-12)
    assert len(record["verdict"]["hits"]) == 6
    assert not [s for s in record["shots"] if any("RECOIL" in str(r) for r in s.get("reasons") or [])]
    code, out, err = cli("verify", "--run", run_id, "--db", lab["db"])
    assert code == 0, out + err


def test_verify_derives_each_runs_ball_cor_from_the_lot(lab: dict[str, Any]) -> None:
    code, out, err = cli("verify", "--db", lab["db"])
    assert code == 0, out + err


def test_a_hot_bat_near_the_limit_with_the_lots_air_measured(tmp_path: Path) -> None:
    """A second softball bat, hotter (hoop 1200 Hz: BPF near 1.24, over the 1.20 limit), on a lot whose
    air sensitivities were measured (ball-cor tests at three hours of the lab's swing of air): the
    hits and the COR are then both moved to the nominal air, the air's bias (about +0.02 in BPF with
    the sensitivities assumed: the ball test ran cool and humid, the bat warm and dry) is corrected,
    and the certified BPF is the simulated truth within a U much smaller than the assumed-air one."""
    from rig.balls import run_ball_test
    from rig.core.ball import BallLot, Conditioning
    from rig.protocols.ball_procedure import BallProcedure
    from rig.session import sim_config
    from tests.balls.test_ball_air import air_starting_at

    scene = no_drag_scene(tmp_path, "softball")
    bat = tmp_path / "hot.toml"
    text = (ROOT / "protocols" / "examples" / "softball-bat.toml").read_text(encoding="utf-8")
    bat.write_text(text.replace("hoop_hz = 1500.0", "hoop_hz = 1200.0").replace("SAMPLE-SB-34", "HOT-SB-34"))
    db = tmp_path / "r.db"
    procedure = BallProcedure.load("ball-cor-fastpitch")
    conditioning = Conditioning(temperature_c=21.0, humidity_pct=50.0, days=14)
    lot = BallLot(id="AIR", maker="m", model="x", balls=120, conditioning=conditioning)
    period = next(e for e in Scene.load(scene).effects if e.kind == "environment").period_s
    with Store.open(db) as store:
        store.register_lot(lot)
        for k in range(3):
            at = air_starting_at(period * (k + 0.25) / 3)
            config = sim_config(str(scene), target=("plate", None), effects=at, ball_class="47/375")
            run_ball_test(store, procedure, lot, config)
    argv = [
        "certify",
        "--procedure",
        "fastpitch-bpf",
        "--bat",
        str(bat),
        "--sim",
        str(scene),
        "--db",
        str(db),
    ]
    code, _, err = cli(*argv, "--ball-lot", "AIR")
    record = json.loads(cli("report", "last", "--db", str(db), "--format", "json")[1])
    verdict, terms = record["verdict"], record["ball"]
    assert terms["conditions_measured"] and verdict["bpf"]["ball_cor_measured"]["air_correction"] != 0.0
    sim = scene_with_bat(Scene.load(scene).with_ball_class("47/375"), BatSpec.load(bat))
    truth = true_metric(sim, tuple(5.0 + 0.5 * i for i in range(6)), "bbcor", 60 * MPH)
    true_bpf = truth.value / rigid_cor(sim.ball, 60 * MPH)
    assert true_bpf > 1.20 and code == 1 and verdict["verdict"] == "FAIL", err
    assert abs(verdict["mean"] - true_bpf) <= verdict["U"] < 0.02, (verdict["mean"], true_bpf, verdict["U"])


@pytest.mark.parametrize("name", list(CASES))
def test_the_bpf_budget_shares_are_of_the_bpfs_u_with_the_lots_terms(lab: dict[str, Any], name: str) -> None:
    """Every term of u(BPF) is in the budget table, its share of u(BPF)² the record's own: the
    shared air, the COR's test and the hits' terms; the largest of them is named."""
    from tests.report.test_budget_shares import budget_rows

    verdict, md = lab[name]["record"]["verdict"], lab[name]["md"]
    parts, u2 = verdict["bpf"], verdict["u"] ** 2
    rows = budget_rows(md)
    assert sum(share for _, share in rows.values()) == pytest.approx(100.0, abs=0.5)
    for key in ("shared_air", "from_ball_cor"):  # the table rounds to 0.1 %
        assert rows[key][1] == pytest.approx(100 * parts[f"u_{key}"] ** 2 / u2, rel=0.01, abs=0.05)
    largest = max(rows, key=lambda k: rows[k][1])
    lead = md.split("Largest contribution: ", 1)[1].split(" % of the result's u²", 1)[0]
    assert lead.endswith(f"{rows[largest][1]:.1f}")


def test_a_lot_tested_with_other_balls_is_blamed_on_its_balls_not_on_its_specification(
    lab: dict[str, Any],
) -> None:
    """A lot registered as 47/375 softballs (COR .47, no mass stated) whose ball-cor test fired
    baseballs: the baseballs' COR fails the lot's specification, but the cause is the balls."""
    folder, db = lab["folder"], lab["db"]
    (folder / "MIXED.toml").write_text(LOT.format(id="MIXED", model="mixed", cor=0.47), encoding="utf-8")
    assert cli("balls", "register", str(folder / "MIXED.toml"), "--db", db)[0] == 0
    scene = lab["usssa-bpf"]["scene"]
    assert (
        cli("balls", "test", "--procedure", "ball-cor", "--lot", "MIXED", "--sim", str(scene), "--db", db)[0]
        == 0
    )
    case = lab["fastpitch-bpf"]
    argv = ["certify", "--procedure", "fastpitch-bpf", "--bat", case["bat"], "--sim", str(case["scene"])]
    code, _, err = cli(*argv, "--db", db, "--ball-lot", "MIXED")
    assert code == 2 and err.count("\n") == 1, err
    assert "fired balls of no ball class" in err and "fails its specification" not in err
    assert "--procedure ball-cor-fastpitch" in err
