"""`rig certify --ball-lot LOT [--ball BALL.json]`: a qualified lot's terms in the record, its rules held."""

from __future__ import annotations

import math
import statistics
from pathlib import Path
from typing import Any

import pytest

from rig.ball_rules import lot_terms
from rig.balls import run_ball_test
from rig.certification import certify, history
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.protocols.ball_procedure import BallProcedure
from rig.protocols.ball_terms import BallTerms
from rig.protocols.procedure import Procedure
from rig.protocols.state import fold
from rig.session import sim_config
from rig.store import Store
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE, run_cli

LOT = """\
[lot]
id = "{id}"
maker = "Acme"
model = "NCAA 1"
balls = {balls}
[lot.specification]
nominal_cor = {nominal}
cor_tolerance = 0.02
[lot.conditioning]
temperature_c = 21.0
humidity_pct = 50.0
days = {days}
"""
RULES = """
[procedure.ball]
replace_after_hits = {replace}
conditioning_days_min = 14.0
air_window_c = 3.0
air_window_pct = 10.0
"""


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A store with lots: L (qualified, 14 days), RAW (never tested), BAD (fails its COR), YOUNG (3 days),
    TWO (qualified, 2 balls); a quick procedure with the ball rules and a bat file beside it."""
    folder = tmp_path_factory.mktemp("lot-lab")
    db = folder / "s.db"
    lots = {
        "L": (24, 0.52, 14),
        "RAW": (24, 0.52, 14),
        "BAD": (24, 0.60, 14),
        "YOUNG": (24, 0.52, 3),
        "TWO": (2, 0.52, 14),
    }
    for lot_id, (balls, nominal, days) in lots.items():
        path = folder / f"{lot_id}.toml"
        path.write_text(LOT.format(id=lot_id, balls=balls, nominal=nominal, days=days), encoding="utf-8")
        assert run_cli(["balls", "register", str(path), "--db", str(db)]).code == 0
    procedure = BallProcedure.load("ball-cor").model_copy(update={"balls_per_speed": 2, "hits_per_ball": 3})
    with Store.open(db) as store:
        for lot_id in ("L", "BAD", "YOUNG", "TWO"):
            lot, _ = store.ball_lot(lot_id)
            run_ball_test(store, procedure, lot, sim_config("lab", target=("plate", None)))
    (folder / "proc.toml").write_text(QUICK_PROCEDURE + RULES.format(replace=12), encoding="utf-8")
    (folder / "tight.toml").write_text(QUICK_PROCEDURE + RULES.format(replace=1), encoding="utf-8")
    (folder / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    return folder


def certify_cli(lab: Path, *extra: str, procedure: str = "proc.toml") -> tuple[int | str | None, str]:
    argv = ["certify", "--procedure", str(lab / procedure), "--bat", str(lab / "bat.toml"), "--sim", "lab"]
    result = run_cli([*argv, "--db", str(lab / "s.db"), *extra])
    return result.code, result.err


@pytest.mark.parametrize(
    ("lot", "cause"),
    [
        ("RAW", "lot RAW is not qualified: no ball-cor test"),
        ("BAD", "lot BAD fails its specification"),
        ("YOUNG", "lot YOUNG was conditioned 3 days; the procedure asks at least 14"),
        ("NOPE", "known lots"),
    ],
)
def test_a_lot_that_does_not_qualify_is_refused_before_anything_is_recorded(
    lab: Path, lot: str, cause: str
) -> None:
    with Store.open(lab / "s.db") as store:
        before = len(store.runs())
    code, err = certify_cli(lab, "--ball-lot", lot)
    assert code == 2 and cause in err, err
    assert len(err.strip().splitlines()) == 1
    with Store.open(lab / "s.db") as store:
        assert len(store.runs()) == before


def test_a_qualified_lot_is_recorded_and_each_valid_hit_names_its_ball(lab: Path) -> None:
    code, err = certify_cli(lab, "--ball-lot", "L")
    assert code in (0, 1), err
    with Store.open(lab / "s.db") as store:
        run = store.runs()[-1].run_id
        state = fold(history(store, run))
        _, results = store.ball_lot("L")
    recorded = state.setup["ball"]
    assert recorded["lot"] == "L" and recorded["balls"] == 24 and recorded["wear_measured"]
    assert recorded["wear_per_hit"] == pytest.approx(results[-1].wear_per_hit)
    assert not recorded["conditions_measured"]  # one ball-cor test cannot tell the air's effect
    fired = [s for s in state.shots if s.raw]
    assert all(str(s.raw.ball).startswith("L-") for s in fired)
    assert fired[0].raw.ball == "L-03"  # the lot's ball-cor test fired L-01 and L-02
    assert [s.raw.ball_hits for s in fired] == list(range(len(fired)))  # one ball, 12 hits allowed
    verdict = state.verdict
    assert verdict is not None and verdict.ball is not None
    assert len(verdict.ball["corrections"]) == len(
        [s for s in state.shots if s.valid and s.purpose != "scan"]
    )


def test_a_ball_law_of_another_lot_is_refused(lab: Path, tmp_path: Path) -> None:
    from tests.ball.synthetic import ccor_points  # a separately written solver's CCOR data

    csv = tmp_path / "ccor.csv"
    csv.write_text(
        "speed_m_s,ccor,u_ccor,ball_id\n"
        + "".join(
            f"{p.speed_m_s},{p.ccor},{p.u_ccor},{p.ball_id}\n" for p in ccor_points(seed=2, with_u=True)
        ),
        encoding="utf-8",
    )
    ball = tmp_path / "ball.json"
    fitted = run_cli(["model", "fit-ball", "--data", str(csv), "--lot", "OTHER", "--output", str(ball)])
    assert fitted.code == 0, fitted.err
    code, err = certify_cli(lab, "--ball-lot", "L", "--ball", str(ball))
    assert code == 2 and "fitted on lot OTHER, not L" in err, err


def test_a_lot_without_enough_unused_balls_is_refused(lab: Path) -> None:
    """Lot TWO has two balls; a procedure that replaces the ball after every hit needs four."""
    code, err = certify_cli(lab, "--ball-lot", "TWO", procedure="tight.toml")
    assert code == 2 and "lot TWO has" in err and "needs at least 4" in err, err


def test_a_run_stops_when_the_lots_balls_are_used_up(lab: Path) -> None:
    """Terms giving the run two balls (bypassing the start's check): the third is refused mid-run."""
    procedure = Procedure.load(lab / "tight.toml")
    bat = BatSpec.load(lab / "bat.toml")
    with Store.open(lab / "s.db") as store:
        terms = lot_terms(store, "L", Procedure.load(lab / "proc.toml"))
        few = terms.model_copy(update={"balls": terms.first_ball + 1})  # two balls left
        outcome = certify(store, procedure, bat, sim_config("lab", bat=bat), ball=few.model_dump())
        assert outcome.status != "finished"
        state = fold(history(store, outcome.run_id))
        stop = [e for e in store.entries(outcome.run_id) if e.kind == ev.RUN_INTERRUPTED]
    first = terms.first_ball
    assert [s.raw.ball for s in state.shots if s.raw] == [f"L-{first:02d}", f"L-{first + 1:02d}"]
    assert stop and f"lot L has {first + 1} balls" in str(stop[-1].payload)


def test_each_run_starts_on_balls_no_earlier_run_fired(lab: Path) -> None:
    """A ball's recorded hit count is its whole history: a run never takes a ball another run hit."""
    with Store.open(lab / "s.db") as store:
        fired_before = {e.payload.get("ball") for e in store.entries(kinds=[ev.SHOT_FIRED])}
    code, err = certify_cli(lab, "--ball-lot", "L")
    assert code in (0, 1), err
    with Store.open(lab / "s.db") as store:
        state = fold(history(store, store.runs()[-1].run_id))
    used = [s.raw.ball for s in state.shots if s.raw]
    assert not set(used) & fired_before
    numbers = sorted(int(b.split("-")[1]) for b in fired_before if str(b).startswith("L-"))
    assert used[0] == f"L-{numbers[-1] + 1:02d}"
    assert state.shots[0].raw.ball_hits == 0


def test_the_air_outside_the_conditioning_window_stops_the_run_before_a_shot(lab: Path) -> None:
    """A lab 4 C warmer than the lot's conditioning (inside the procedure's 18-26 C): no shot, resumable."""
    procedure = Procedure.load(lab / "proc.toml")
    bat = BatSpec.load(lab / "bat.toml")
    warm = {"environment": {"temp_c": 25.0, "temp_swing_c": 0.0, "random_start": False}}
    with Store.open(lab / "s.db") as store:
        terms = lot_terms(store, "L", procedure)
        outcome = certify(
            store, procedure, bat, sim_config("lab", bat=bat, effects=warm), ball=terms.model_dump()
        )
        assert outcome.status != "finished"
        entries = store.entries(outcome.run_id)
    kinds = [e.kind for e in entries]
    assert ev.SHOT_FIRED not in kinds
    interrupted = [e for e in entries if e.kind == ev.RUN_INTERRUPTED]
    assert interrupted and "outside lot L's conditioning window (21 +- 3 C" in str(interrupted[-1].payload)


def test_the_rules_are_procedure_data_and_none_means_none(lab: Path) -> None:
    with Store.open(lab / "s.db") as store:
        # the built-in BBCOR procedure asks 14 days; a procedure without rules takes YOUNG
        with pytest.raises(ConfigError, match="at least 14"):
            lot_terms(store, "YOUNG", Procedure.load("bbcor"))
        assert (
            lot_terms(
                store,
                "YOUNG",
                Procedure.load(lab / "proc.toml").model_copy(update={"ball": Procedure.load("bbs").ball}),
            ).lot
            == "YOUNG"
        )


def test_ball_cor_tests_at_three_hours_from_the_cli_measure_the_air(tmp_path: Path) -> None:
    """The whole path as a lab on the simulated rig would type it: register, three ball-cor tests at
    different hours of the lab's air, certify; the run's terms have the air measured and corrected."""
    db, lot = tmp_path / "s.db", tmp_path / "lot.toml"
    lot.write_text(LOT.format(id="AIRLOT", balls=24, nominal=0.52, days=14), encoding="utf-8")
    assert run_cli(["balls", "register", str(lot), "--db", str(db)]).code == 0
    for start in ("0", "1200", "2400"):
        test = [
            "balls",
            "test",
            "--procedure",
            "ball-cor",
            "--lot",
            "AIRLOT",
            "--sim",
            "lab",
            "--db",
            str(db),
        ]
        done = run_cli([*test, "--sim-start", start])
        assert done.code == 0, done.err
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE + RULES.format(replace=12), encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    code, err = certify_cli(tmp_path, "--ball-lot", "AIRLOT")
    assert code in (0, 1), err
    with Store.open(db) as store:
        state = fold(history(store, store.runs()[-1].run_id))
        _, results = store.ball_lot("AIRLOT")
    terms = state.setup["ball"]
    assert terms["conditions_measured"] and terms["air_cov"] is not None
    assert len({round(r.temp_c or 0.0, 1) for r in results}) == 3  # three hours, three airs
    hits = [s for s in state.shots if s.valid and s.purpose != "scan"]
    assert all(s.requested.temperature_c is not None for s in hits)  # the air read before each shot
    assert state.verdict is not None and state.verdict.ball is not None
    assert state.verdict.ball["u_conditions"] < 0.002


def test_the_hits_scatter_in_the_budget_is_that_of_the_corrected_hits(tmp_path: Path) -> None:
    """The result averages the corrected hits, so their scatter is the Type A term: with a large
    measured wear the corrections spread the hits far more than the rig does, and u must show it."""
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE + RULES.format(replace=12), encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    procedure, bat = Procedure.load(tmp_path / "proc.toml"), BatSpec.load(tmp_path / "bat.toml")
    terms = BallTerms(lot="W", wear_measured=True, wear_per_hit=-0.01, wear_per_hit_u=0.0)
    with Store.open(tmp_path / "s.db") as store:
        outcome = certify(store, procedure, bat, sim_config("ideal", bat=bat), ball=terms.model_dump())
        state = fold(history(store, outcome.run_id))
    v = state.verdict
    assert v is not None and v.ball is not None
    hits = [s for s in state.shots if s.valid and s.purpose != "scan"]
    corrected = [float(s.metric or 0.0) + c for s, c in zip(hits, v.ball["corrections"], strict=True)]
    type_a = statistics.stdev(corrected) / math.sqrt(len(corrected))
    measured = [float(s.metric or 0.0) for s in hits]
    assert type_a > 3 * statistics.stdev(measured) / math.sqrt(len(measured))  # the corrections spread them
    assert v.ball["u_measurement"] >= type_a * (1 - 1e-9)


def test_the_lots_recorded_law_is_used_and_named_without_ball(lab: Path, tmp_path: Path) -> None:
    """A ball file named by the lot: the law recorded for the lot is the run's (its sha256 recorded),
    unless --ball names another; a law of another lot cannot be recorded for this one."""
    from rig.ball_rules import record_lot_law
    from rig.core.errors import ConfigError, UnknownRecord
    from rig.physics.ball_law import BallLaw
    from tests.ball.synthetic import write_ccor_csv

    csv = write_ccor_csv(tmp_path / "ccor.csv", seed=3)
    mine, other = tmp_path / "mine.json", tmp_path / "other.json"
    for lot, path in (("L", mine), ("OTHER", other)):
        done = run_cli(["model", "fit-ball", "--data", str(csv), "--lot", lot, "--output", str(path)])
        assert done.code == 0, done.err
    with Store.open(lab / "s.db") as store:
        with pytest.raises(ConfigError, match="fitted on lot OTHER, not lot L"):
            record_lot_law(store, "L", str(other))
        with pytest.raises(UnknownRecord, match="no ball lot 'NOPE'"):
            store.record_ball_law("NOPE", mine.read_text(encoding="utf-8"))
        _, sha = record_lot_law(store, "L", str(mine))
    assert sha == BallLaw.read(mine)[1]
    code, err = certify_cli(lab, "--ball-lot", "L")
    assert code in (0, 1), err
    with Store.open(lab / "s.db") as store:
        state = fold(history(store, store.runs()[-1].run_id))
    recorded = state.setup["ball"]
    assert recorded["law"] == pytest.approx(dict(BallLaw.load(mine).constants))
    assert recorded["law_sha256"] == sha and recorded["law_from"] == "lot L's recorded law"
    # the model's prediction beside the verdict is made with the run's ball law, not the paper's
    from rig.measure.metrics import compute_metrics
    from rig.physics import DEFAULT_PARAMS, CollisionParams, PivotedBat, predict_bat

    verdict = state.verdict
    assert verdict is not None
    cc, q, moi = verdict.cross_check, verdict.impact_from_pivot_m, verdict.moi_kgm2
    v_in = statistics.mean(
        h.outcome.inbound_at_impact_m_s for h in state.valid_shots("valid", state.best_location_in)
    )
    bat = BatSpec.load(lab / "bat.toml")

    def predicted(params: CollisionParams) -> float:
        e_a = predict_bat(params, v_in, bat.hoop_hz, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)).e_a
        return float(compute_metrics(v_in, e_a * v_in, q, moi, params.m1, bat.length_m).bbcor)

    mass = {"m1": state.setup["ball"].get("law", {}).get("m1", DEFAULT_PARAMS.m1)}
    with_law = DEFAULT_PARAMS.model_copy(update={**mass, **recorded["law"]})
    assert cc["predicted"] == pytest.approx(predicted(with_law), abs=1e-9)
    assert abs(predicted(with_law) - predicted(DEFAULT_PARAMS.model_copy(update=mass))) > 1e-4
    assert run_cli(["verify", "--db", str(lab / "s.db")]).code == 0
    cert = tmp_path / "cert.md"
    assert run_cli(["report", "last", "--db", str(lab / "s.db"), "--output", str(cert)]).code == 0
    assert f"lot L's recorded law, sha256 {sha[:12]}" in cert.read_text(encoding="utf-8")


def _tampered(lab: Path, folder: Path, run: str, edit: Any) -> list[str]:
    """ball_terms_problems of a copy of the lab's store whose run's recorded ball terms `edit` changed."""
    import json
    import shutil
    import sqlite3

    from rig.balls import ball_terms_problems

    folder.mkdir()
    for suffix in ("", "-wal", "-shm"):
        if (lab / f"s.db{suffix}").exists():
            shutil.copy(lab / f"s.db{suffix}", folder / f"copy.db{suffix}")
    with sqlite3.connect(folder / "copy.db") as conn:  # someone rewrites the run's record
        conn.execute("DROP TRIGGER log_no_update")
        seq, payload = conn.execute(
            "SELECT seq, payload FROM log WHERE run_id = ? AND kind = 'RunStarted'", (run,)
        ).fetchone()
        data = json.loads(payload)
        edit(data["ball"])
        conn.execute("UPDATE log SET payload = ? WHERE seq = ?", (json.dumps(data), seq))
    with Store.open(folder / "copy.db") as again:
        return ball_terms_problems(again)


def test_verify_derives_a_certifications_ball_terms_again(lab: Path, tmp_path: Path) -> None:
    """The terms name the ball-cor runs they rest on (every one of the lot's, finished before the
    run); verify derives them again from exactly those and names what differs."""
    from rig.balls import ball_terms_problems

    code, err = certify_cli(lab, "--ball-lot", "L")
    assert code in (0, 1), err
    with Store.open(lab / "s.db") as store:
        run = store.runs()[-1].run_id
        recorded = fold(history(store, run)).setup["ball"]
        _, results = store.ball_lot("L")
        assert recorded["results"] == [r.run_id for r in results if r.procedure == "ball-cor"]
        assert ball_terms_problems(store) == []

    def smaller_wear(terms: dict[str, Any]) -> None:
        terms["wear_per_hit"] = -1e-05

    def no_results(terms: dict[str, Any]) -> None:
        terms["results"] = []

    def unknown_field(terms: dict[str, Any]) -> None:
        terms["made_up"] = 1

    def another_lot(terms: dict[str, Any]) -> None:
        terms["lot"] = "NOT-HERE"  # e.g. a run copied by rig sync, which copies no lots

    cases = [
        (smaller_wear, f"run {run}: its recorded ball terms are not what lot L's results give (wear_per_hit"),
        (no_results, f"run {run}: its ball terms rest on ball-cor runs none, not on lot L's tests before it"),
        (unknown_field, f"run {run}: its recorded ball terms are unreadable"),
    ]
    for i, (edit, said) in enumerate(cases):
        problems = _tampered(lab, tmp_path / f"t{i}", run, edit)
        assert any(p.startswith(said) for p in problems), (edit.__name__, problems)
    assert _tampered(lab, tmp_path / "sync", run, another_lot) == []  # not derivable here: not a problem
