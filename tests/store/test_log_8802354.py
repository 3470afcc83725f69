"""A database written by the code of commit 8802354 (tests/fixtures/log-8802354.db), the last whose
shot outcomes, verdicts and MOI results were untyped payload dicts, still verifies, folds into its
resume state, reports, lists and exports byte for byte as that code did."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import statistics
from pathlib import Path

import pytest

from rig.certification import history
from rig.cli import main
from rig.protocols.state import fold
from rig.store import Store

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
NAME = "log-8802354"
RUNS: dict[str, str] = json.loads((FIXTURES / f"{NAME}.runs.json").read_text())
CERTIFIED = ("bbcor_lot", "besr", "bbs", "resumed")


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the fixture (opening a store may touch it; the committed file stays as written)."""
    copy = tmp_path_factory.mktemp("log8802354") / f"{NAME}.db"
    shutil.copyfile(FIXTURES / f"{NAME}.db", copy)
    return copy


def _cli(argv: list[str]) -> str:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    assert code == 0, err.getvalue()
    return out.getvalue()


def test_the_database_verifies(db: Path) -> None:
    with Store.open(db) as store:
        report = store.verify()
        assert report.ok, report
        statuses = {r.run_id: r.status for r in store.runs()}
    assert statuses == {
        **{RUNS[n]: "finished" for n in ("ball_test", *CERTIFIED)},
        RUNS["shot"]: "aborted",
        RUNS["ended"]: "aborted",
    }


def test_the_runs_fold_into_their_resume_state(db: Path) -> None:
    with Store.open(db) as store:
        states = {name: fold(history(store, run_id)) for name, run_id in RUNS.items()}
        raw = {name: store.entries(run_id) for name, run_id in RUNS.items()}
    for name in CERTIFIED:
        st = states[name]
        assert st.finished and st.pending is None and st.ended is None
        v = st.verdict
        assert v is not None and v.n_hits == len(v.hits) >= 3
        assert v.mean == pytest.approx(statistics.fmean(v.hits), abs=1e-15)
        assert (v.verdict == "PASS") == (v.mean + v.U <= v.limit)
        assert pytest.approx(v.coverage_k * v.u, rel=1e-15) == v.U
        requested = [e.payload["index"] for e in raw[name] if e.kind == "ShotRequested"]
        assert [s.index for s in st.shots] == requested
        assert len(st.valid_shots("valid", st.best_location_in)) == v.n_hits
        assert st.moi is not None and st.moi.moi_kgm2 == v.moi_kgm2
    assert states["bbcor_lot"].verdict.ball is not None  # the lot's ball terms corrected the verdict
    assert states["bbs"].verdict.metric == "bbs"
    ended = states["ended"]
    assert not ended.finished and ended.verdict is None
    assert ended.ended is not None and ended.ended.who == "Q. Manager"
    shot = states["shot"]
    assert len(shot.shots) == 1 and shot.shots[0].valid is not None and shot.verdict is None


@pytest.mark.parametrize(
    ("name", "fmt"),
    [(n, f) for n in sorted(RUNS) for f in ("json", "md") if (n, f) != ("shot", "md")],
)
def test_the_runs_report_as_they_did(db: Path, name: str, fmt: str) -> None:
    figures = db.parent / "figures"
    text = _cli(["report", RUNS[name], "--format", fmt, "--db", str(db), "--figures", str(figures)])
    text = text.replace(str(figures), "FIGURES")
    golden = (FIXTURES / f"{NAME}.{name}.{fmt}").read_text()
    if fmt == "json":
        assert json.loads(text) == json.loads(golden)
    assert text == golden


def test_the_runs_list_and_export_as_they_did(db: Path) -> None:
    assert _cli(["runs", "--json", "--db", str(db)]) == (FIXTURES / f"{NAME}.runs-list.json").read_text()
    for view in ("shots", "runs_summary"):
        text = _cli(["export", "--view", view, "--output", "-", "--db", str(db)])
        assert text == (FIXTURES / f"{NAME}.{view}.csv").read_text()


def test_the_console_and_the_report_show_what_the_one_fold_says(db: Path) -> None:
    from rig.report.record import run_record
    from rig.tui.live import LiveRun

    with Store.open(db) as store:
        for name, run_id in RUNS.items():
            if name in ("ball_test", "shot"):  # the console runs certifications; these show as reports
                continue
            events = history(store, run_id)
            st, record, live = fold(events), run_record(store, run_id), LiveRun()
            for e in events:
                live.apply(e)
            statuses = {s.index: s.status for s in st.shots}
            assert statuses == {s["index"]: s["status"] for s in record["shots"]}
            assert statuses == {i: s.status for i, s in live.shots.items()}
            assert live.run == st
            assert [i["kind"] for i in record["interruptions"]] == [n.kind for n in st.stops]
