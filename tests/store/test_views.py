"""The analysts' views `shots` and `runs_summary`: every row checked against the run's record.

The record (rig.report.record.run_record, the fold the certificate uses) and the raw log entries
are the independent side; the views are SQL over the same log and must agree with them.
"""

from __future__ import annotations

import re
import shutil
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import SCHEMA_VERSION, Store
from rig.store._views import POSTGRES_VIEWS, SQLITE_VIEWS, VIEW_COLUMNS
from tests.store import handmade

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
FIXTURES = ROOT / "tests" / "fixtures"


class ReviewingOperator:
    """Accepts every prompt except the review of one shot, which it rejects (a ShotOverruled)."""

    who = "reviewer"

    def __init__(self, reject: str) -> None:
        self.reject = reject

    def ask(self, prompt_id: str, text: str) -> bool:
        return prompt_id != self.reject


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """A store with simulated runs: BBCOR lab (PASS, rejected shots), faulty (lost shots,
    interrupted), BESR ideal, BBCOR ideal with one valid shot overruled on review."""
    path = tmp_path_factory.mktemp("views") / "r.db"
    runs = {}
    with Store.open(path) as store:
        for name, scene in (("lab", "lab"), ("faulty", "faulty")):
            config = sim_config(scene, bat=SAMPLE_BAT)
            runs[name] = certify(store, Procedure.load("bbcor"), SAMPLE_BAT, config).run_id
        besr = Procedure.load("besr")
        runs["besr"] = certify(store, besr, SAMPLE_BAT, sim_config("ideal", bat=SAMPLE_BAT)).run_id
        runs["reviewed"] = certify(
            store,
            Procedure.load("bbcor"),
            SAMPLE_BAT,
            sim_config("ideal", bat=SAMPLE_BAT),
            operator=ReviewingOperator("review-2"),
            review_shots=True,
        ).run_id
    return path, runs


def shots_from_record(store: Store, run_id: str) -> list[dict[str, Any]]:
    """The `shots` rows a run's record implies: each fired shot, its request and outcome."""
    record = run_record(store, run_id)
    fired = {e.payload["index"]: e.t_utc for e in store.entries(run_id, kinds=["ShotFired"])}
    created = store.entries(run_id, kinds=["RunCreated"])[0].payload
    rig = ((created.get("meta") or {}).get("rig") or {}).get("name")
    rows = []
    for shot in record["shots"]:
        if "raw" not in shot:  # requested, never fired
            continue
        rows.append(
            {
                "run_id": run_id,
                "rig": rig,
                "bat_id": record["bat"]["id"],
                "shot_index": shot["index"],
                "purpose": shot["purpose"],
                "location_in": shot["location_in"],
                "inbound_speed_m_s": shot.get("inbound_speed_m_s"),
                "rebound_speed_m_s": shot.get("rebound_speed_m_s"),
                "metric": shot.get("metric"),
                "u": shot.get("u"),
                "valid": shot.get("valid"),
                "reasons": ",".join(r["code"] for r in shot.get("reasons", [])),
                "t_utc": fired[shot["index"]],
            }
        )
    return rows


def summary_from_record(store: Store, run_id: str) -> dict[str, Any]:
    """The `runs_summary` row a run's record implies."""
    record = run_record(store, run_id)
    verdict = record["verdict"] or {}
    closed = [
        e.t_utc
        for e in store.entries(run_id, kinds=["RunStatusChanged"])
        if e.payload["status"] in ("finished", "aborted")
    ]
    created = store.entries(run_id, kinds=["RunCreated"])[0].payload
    return {
        "run_id": run_id,
        "rig": ((created.get("meta") or {}).get("rig") or {}).get("name"),
        "bat_id": created["bat_id"],
        "procedure": created["procedure"],
        # the view speaks the store's words (an ended run 'aborted', an interrupted one 'running')
        "status": {"ended": "aborted", "interrupted": "running"}.get(record["status"], record["status"]),
        "verdict": verdict.get("verdict"),
        "mean": verdict.get("mean"),
        "expanded_uncertainty": verdict.get("U"),
        "k": verdict.get("coverage_k"),
        "started_utc": record["started_utc"],
        "finished_utc": closed[0] if closed else None,
    }


def test_every_shot_row_matches_the_record(lab: tuple[Path, dict[str, str]]) -> None:
    path, runs = lab
    with Store.open(path, create=False) as store:
        for run_id in runs.values():
            rows = sorted(store.view_rows("shots", run_id), key=lambda r: r["shot_index"])
            assert rows == shots_from_record(store, run_id), run_id
        everything = store.view_rows("shots")
    assert len(everything) == sum(1 for e in _log(path) if e[1] == "ShotFired")
    # the runs hold what a lab sees: invalid shots with their reasons, a lost one, an overruled one
    assert any(r["valid"] is False and r["reasons"] and r["reasons"] != "LOST" for r in everything)
    assert any(r["valid"] is True for r in everything)
    reviewed = [r for r in everything if r["run_id"] == runs["reviewed"] and r["shot_index"] == 2]
    assert reviewed[0]["valid"] is False and reviewed[0]["reasons"] == "OPERATOR_REJECTED"
    faulty = [r for r in everything if r["run_id"] == runs["faulty"]]
    assert any(r["valid"] is False for r in faulty)
    assert any(kind == "ShotLost" for run, kind in _log(path) if run == runs["faulty"])


def test_every_summary_row_matches_the_record(lab: tuple[Path, dict[str, str]]) -> None:
    path, runs = lab
    with Store.open(path, create=False) as store:
        rows = {r["run_id"]: r for r in store.view_rows("runs_summary")}
        assert set(rows) == set(runs.values())
        for run_id in runs.values():
            assert rows[run_id] == summary_from_record(store, run_id)
            summary = store.run(run_id)  # the store's own table agrees on status and verdict
            assert (rows[run_id]["status"], rows[run_id]["verdict"]) == (summary.status, summary.verdict)
    assert rows[runs["lab"]]["verdict"] == "PASS" and rows[runs["lab"]]["mean"] < 0.5
    assert rows[runs["besr"]]["procedure"] == "besr" and rows[runs["besr"]]["k"] == 2.0
    assert rows[runs["faulty"]]["status"] == "running" and rows[runs["faulty"]]["finished_utc"] is None


def test_the_views_are_plain_sql_an_analyst_can_query(lab: tuple[Path, dict[str, str]]) -> None:
    """No rig code needed: the sqlite3 module alone reads the views (valid as 1/0)."""
    path, runs = lab
    conn = sqlite3.connect(path)
    try:
        n_valid, n_invalid = conn.execute(
            "SELECT count(*) FILTER (WHERE valid = 1), count(*) FILTER (WHERE valid = 0) FROM shots "
            "WHERE run_id = ?",
            (runs["lab"],),
        ).fetchone()
        mean = conn.execute("SELECT mean FROM runs_summary WHERE run_id = ?", (runs["lab"],)).fetchone()[0]
    finally:
        conn.close()
    with Store.open(path, create=False) as store:
        shots = run_record(store, runs["lab"])["shots"]
        verdict = run_record(store, runs["lab"])["verdict"]
    assert n_valid == sum(1 for s in shots if s.get("valid") is True)
    assert n_invalid == sum(1 for s in shots if s.get("valid") is False and "raw" in s)
    assert mean == verdict["mean"]


def test_a_hand_made_run_gives_the_rows_written_down(tmp_path: Path) -> None:
    """Overruled, rejected with two reasons, lost after firing, lost before, pending; rig from meta."""
    path = tmp_path / "h.db"
    with Store.open(path) as store:
        run_id = handmade.build(store)
        fired = {e.payload["index"]: e.t_utc for e in store.entries(run_id, kinds=["ShotFired"])}
        closing = store.entries(run_id, kinds=["RunStatusChanged"])[0].t_utc
        started = store.run(run_id).started_utc
        assert store.view_rows("shots", run_id) == handmade.expected_shots(run_id, fired)
        assert store.view_rows("runs_summary") == [handmade.expected_summary(run_id, started, closing)]
        assert store.view_rows("shots", "no-such-run") == []


def test_entries_after_the_seal_are_not_in_the_views(tmp_path: Path) -> None:
    """A shot and a FAIL forged onto a closed run with plain SQL: the views show the run as sealed,
    as its certificate does (and verify reports the forgery)."""
    path = tmp_path / "h.db"
    with Store.open(path) as store:
        run_id = handmade.build(store)
        before = (store.view_rows("shots"), store.view_rows("runs_summary"))
    handmade.forge_after_seal(path, run_id)
    with Store.open(path, create=False) as store:
        assert (store.view_rows("shots"), store.view_rows("runs_summary")) == before
        assert not store.verify().ok
        assert run_record(store, run_id)["verdict"]["verdict"] == "PASS"


def test_an_old_store_gains_the_views_and_they_read_its_runs(tmp_path: Path) -> None:
    db = tmp_path / "log-v1.db"
    shutil.copyfile(FIXTURES / "log-v1.db", db)
    assert _views_in(db) == set()  # written before the views existed
    with Store.open(db, create=False) as store:
        assert store.verify().ok
        run_ids = [r.run_id for r in store.runs()]
        assert len(run_ids) == 3
        for run_id in run_ids:
            rows = sorted(store.view_rows("shots", run_id), key=lambda r: r["shot_index"])
            assert rows == shots_from_record(store, run_id)
            (summary,) = store.view_rows("runs_summary", run_id)
            assert summary == summary_from_record(store, run_id)
        assert {r["status"] for r in store.view_rows("runs_summary")} == {"finished", "aborted"}
        assert any(r["valid"] is False for r in store.view_rows("shots"))
    assert _views_in(db) == {"shots", "runs_summary"}
    conn = sqlite3.connect(db)
    try:
        versions = [v for (v,) in conn.execute("SELECT version FROM schema_version ORDER BY version")]
    finally:
        conn.close()
    assert versions == list(range(1, SCHEMA_VERSION + 1)) and SCHEMA_VERSION >= 3


def test_an_unknown_view_is_named(tmp_path: Path) -> None:
    from rig.store import UnknownRecord

    with Store.open(tmp_path / "e.db") as store, pytest.raises(UnknownRecord, match="no view 'shot'; the"):
        store.view_rows("shot")


def test_both_engines_define_the_same_columns_in_the_same_order() -> None:
    """The PostgreSQL text reads JSON with jsonb operators, never json_extract, into the same columns."""
    for sqlite_sql, pg_sql, view in zip(SQLITE_VIEWS, POSTGRES_VIEWS, VIEW_COLUMNS, strict=True):
        assert sqlite_sql.startswith(f"CREATE VIEW {view} AS") and pg_sql.startswith(f"CREATE VIEW {view} AS")
        names = [name for name, _ in VIEW_COLUMNS[view]]
        assert _select_aliases(sqlite_sql) == names == _select_aliases(pg_sql)
        assert "json_extract" not in pg_sql and "json_each" not in pg_sql and "::jsonb" in pg_sql
        assert "::jsonb" not in sqlite_sql


def _select_aliases(sql: str) -> list[str]:
    """The column aliases of a view's final SELECT (after its WITH clause)."""
    final = sql[sql.rindex("\nSELECT\n") :]
    final = final[: final.index("\nFROM ")]
    return re.findall(r" AS (\w+),?\n", final + "\n")


def _views_in(path: Path) -> set[str]:
    conn = sqlite3.connect(path)
    try:
        return {name for (name,) in conn.execute("SELECT name FROM sqlite_master WHERE type = 'view'")}
    finally:
        conn.close()


def _log(path: Path) -> list[tuple[str, str]]:
    conn = sqlite3.connect(path)
    try:
        return list(conn.execute("SELECT run_id, kind FROM log ORDER BY seq"))
    finally:
        conn.close()
