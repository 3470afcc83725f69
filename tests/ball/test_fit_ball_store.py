"""`rig model fit-ball --db STORE --lot LOT`: the ball law fitted to a lot's ccor tests in the store.

End to end through the CLI: a lot registered, measured on the simulated lab rig through the real
drivers (a `ball-cor` test, whose flat-plate COR must not be fitted, and two `ccor` tests), then
fitted from the store; and the refusals, each one line naming its cause.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path

import pytest

from rig.cli import main
from rig.physics.ball_law import BallLaw
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
LOT = '[lot]\nid = "{id}"\nmaker = "Acme"\nmodel = "NCAA-1"\nballs = 24\n'


def cli(argv: list[str]) -> tuple[int, str, str]:
    """main(argv): exit status, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def register(db: Path, lot_id: str) -> None:
    lot_file = db.with_name(f"{lot_id}.toml")
    lot_file.write_text(LOT.format(id=lot_id), encoding="utf-8")
    code, _, err = cli(["balls", "register", str(lot_file), "--db", str(db)])
    assert code == 0, err


def smaller(test: str, tmp_path: Path, **fields: int) -> str:
    """A copy of the built-in test's file with fewer balls or hits (the same speeds and target)."""
    text = (ROOT / "protocols" / f"{test}.toml").read_text(encoding="utf-8")
    for name, value in fields.items():
        line = next(s for s in text.splitlines() if s.startswith(f"{name} ="))
        text = text.replace(line, f"{name} = {value}")
    path = tmp_path / f"{test}-small.toml"
    path.write_text(text, encoding="utf-8")
    return str(path)


def ball_test(db: Path, procedure: str, lot_id: str) -> dict[str, object]:
    argv = ["balls", "test", "--procedure", procedure, "--lot", lot_id, "--sim", "lab", "--db", str(db)]
    code, out, err = cli([*argv, "--json"])
    assert code == 0, err
    done: dict[str, object] = json.loads(out)
    return done


def fit(db: Path, lot_id: str | None, output: Path, *extra: str) -> tuple[int, str, str]:
    lot = ["--lot", lot_id] if lot_id else []
    return cli(["model", "fit-ball", "--db", str(db), *lot, "--output", str(output), *extra])


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_a_lots_ccor_tests_on_the_lab_rig_fit_the_ball_law(tmp_path: Path) -> None:
    db, ball = tmp_path / "lab.db", tmp_path / "ball.json"
    register(db, "ACME-1")
    plate = ball_test(db, smaller("ball-cor", tmp_path, balls_per_speed=2, hits_per_ball=2), "ACME-1")

    # a flat-plate COR is not CCOR: with only a ball-cor result there is nothing to fit
    code, _, err = fit(db, "ACME-1", ball)
    assert code == 2 and not ball.exists()
    assert "ball lot 'ACME-1' has no finished ccor test (its results: ball-cor only)" in one_line(err)

    first = ball_test(db, "ccor", "ACME-1")  # the built-in test: 5 speeds x 3 balls, one hit each
    second = ball_test(db, smaller("ccor", tmp_path, balls_per_speed=2), "ACME-1")
    code, out, err = fit(db, "ACME-1", ball)
    assert code == 0, err
    assert f"from the store's ccor test run(s): {first['run_id']}, {second['run_id']}" in out

    law = BallLaw.load(ball)
    prov = law.provenance
    with Store.open(db, create=False) as store:
        hits = store.ccor_points("ACME-1")  # every valid hit of the finished ccor tests
        _, results = store.ball_lot("ACME-1")
    assert [r.procedure for r in results] == ["ball-cor", "ccor", "ccor"]
    assert [r.n_hits for r in results[1:]] == [15, 10]
    assert prov.lot == "ACME-1" and prov.runs == [first["run_id"], second["run_id"]]
    assert plate["run_id"] not in prov.runs
    assert prov.n_points == len(hits) == 25 and len(law.points) == 25
    assert prov.n_balls == len({ball_id for *_, ball_id in hits})
    assert prov.n_speeds == 5 and 24.0 < prov.speed_min_m_s < 26.0 and 59.0 < prov.speed_max_m_s < 61.0
    assert sorted(p["speed_m_s"] for p in law.points) == sorted(speed for speed, *_ in hits)
    assert {p["group"] for p in law.points} == {ball_id for *_, ball_id in hits}  # left out ball by ball
    assert all(p["u_ccor"] is not None for p in law.points)  # each hit's own u weights it
    assert prov.data_file == f"store {db}, lot ACME-1" and len(prov.data_sha256) == 64
    for value in [*law.constants.values(), *law.parameters.values(), *law.uncertainty.values()]:
        assert math.isfinite(value)
    assert (
        {"a", "b"} <= set(law.parameters)
        and 0.0 < law.constants["a"] < 1.0
        and 0.0 < law.constants["b"] < 1.0
    )

    # the same records give the same data hash; nothing in the store changed
    again = tmp_path / "again.json"
    assert fit(db, "ACME-1", again)[0] == 0
    assert BallLaw.load(again).provenance.data_sha256 == prov.data_sha256
    code, out, _ = cli(["verify", "--db", str(db)])
    assert code == 0 and out.startswith("ok:")

    # each fit from the store is recorded as the lot's ball law (the latest is the lot's), byte for byte
    with Store.open(db, create=False) as store:
        laws = store.ball_laws("ACME-1")
    assert [w.sha256 for w in laws] == [BallLaw.read(p)[1] for p in (ball, again)]
    assert laws[-1].text.encode("utf-8") == again.read_bytes()
    named = tmp_path / "named.json"
    code, _, err = cli(["balls", "law", "ACME-1", "--db", str(db), "--output", str(named)])
    assert code == 0 and named.read_bytes() == again.read_bytes(), err
    code, out, _ = cli(["balls", "show", "ACME-1", "--db", str(db)])
    assert out.count("ball law recorded") == 2 and laws[-1].sha256[:12] in out


@pytest.fixture
def db(tmp_path: Path) -> Path:
    """A store with two lots registered and no test run."""
    where = tmp_path / "records.db"
    register(where, "ACME-1")
    register(where, "ACME-2")
    return where


def test_an_unknown_lot_is_named_with_the_known_ones(db: Path, tmp_path: Path) -> None:
    code, _, err = fit(db, "NOPE", tmp_path / "b.json")
    assert code == 2 and "no ball lot 'NOPE'; known lots: ACME-1, ACME-2" in one_line(err)
    assert not (tmp_path / "b.json").exists()


def test_a_lot_without_a_finished_ccor_test_is_refused(db: Path, tmp_path: Path) -> None:
    code, _, err = fit(db, "ACME-2", tmp_path / "b.json")
    line = one_line(err)
    assert (
        code == 2 and "ball lot 'ACME-2' has no finished ccor test (no ball test of it has finished)" in line
    )
    assert "rig balls test --procedure ccor --lot ACME-2" in line


def test_a_missing_or_unreadable_store_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "b.json"
    missing = tmp_path / "missing.db"
    code, _, err = fit(missing, "ACME-1", out)
    assert code == 2 and "missing.db: no such store" in one_line(err)
    assert not missing.exists()  # fit-ball never creates a store
    garbage = tmp_path / "garbage.db"
    garbage.write_bytes(b"\x00\xffnot a store at all\x89PNG" * 200)
    code, _, err = fit(garbage, "ACME-1", out)
    assert code == 2 and "garbage.db: not a SQLite database" in one_line(err)
    code, _, err = fit(tmp_path, "ACME-1", out)  # a directory
    assert code == 2 and "is a directory, not a store file" in one_line(err)
    assert not out.exists()


def test_data_and_db_together_are_refused(db: Path, tmp_path: Path) -> None:
    csv = tmp_path / "ccor.csv"
    csv.write_text("speed_m_s,ccor\n25,0.52\n", encoding="utf-8")
    code, _, err = fit(db, "ACME-1", tmp_path / "b.json", "--data", str(csv))
    assert code == 2 and "give --data CCOR.csv or --db STORE --lot LOT, not both" in one_line(err)


def test_db_needs_a_lot_and_some_source_is_needed(db: Path, tmp_path: Path) -> None:
    code, _, err = fit(db, None, tmp_path / "b.json")
    assert code == 2 and "--db needs --lot LOT" in one_line(err)
    code, _, err = cli(["model", "fit-ball", "--output", str(tmp_path / "b.json")])
    assert code == 2 and "give --data CCOR.csv or --db STORE --lot LOT" in one_line(err)


def test_the_output_may_not_overwrite_the_store(db: Path) -> None:
    before = db.read_bytes()
    code, _, err = fit(db, "ACME-1", db)
    assert code == 2 and "--output would overwrite the record store" in one_line(err)
    assert db.read_bytes() == before


def test_a_lot_without_a_recorded_law_says_how_to_record_one(db: Path, tmp_path: Path) -> None:
    code, _, err = cli(["balls", "law", "ACME-2", "--db", str(db), "--output", str(tmp_path / "b.json")])
    line = one_line(err)
    assert code == 2 and "lot ACME-2 has no recorded ball law" in line and "fit-ball --db" in line
    assert not (tmp_path / "b.json").exists()
    code, _, err = cli(["balls", "law", "NOPE", "--db", str(db), "--output", str(tmp_path / "b.json")])
    assert code == 2 and "no ball lot 'NOPE'" in one_line(err)


def test_balls_law_never_overwrites_the_store_and_writes_an_earlier_law_by_entry(tmp_path: Path) -> None:
    from tests.ball.synthetic import write_ccor_csv

    db = tmp_path / "lab.db"
    register(db, "ACME-1")
    csv = write_ccor_csv(tmp_path / "ccor.csv", seed=4)
    from rig.ball_rules import record_lot_law

    files = []
    for i, extra in enumerate(([], ["--set", "c1=5200"])):
        path = tmp_path / f"law{i}.json"
        code, _, err = cli(
            ["model", "fit-ball", "--data", str(csv), "--lot", "ACME-1", "--output", str(path), *extra]
        )
        assert code == 0, err
        files.append(path)
    with Store.open(db) as store:
        entries = [record_lot_law(store, "ACME-1", str(p))[0].seq for p in files]
    before = db.read_bytes()
    code, _, err = cli(["balls", "law", "ACME-1", "--db", str(db), "--output", str(db)])
    assert code == 2 and "--output would overwrite the record store" in one_line(err)
    assert db.read_bytes() == before
    out = tmp_path / "first.json"
    code, _, err = cli(
        ["balls", "law", "ACME-1", "--db", str(db), "--output", str(out), "--entry", str(entries[0])]
    )
    assert code == 0 and out.read_bytes() == files[0].read_bytes(), err
    code, _, err = cli(["balls", "law", "ACME-1", "--db", str(db), "--output", str(out), "--entry", "99999"])
    assert code == 2 and f"its laws: {entries[0]}, {entries[1]}" in one_line(err)
