"""A database written by the log format 1 code (tests/fixtures/log-v1.db) still verifies,
resumes (its fold) and reports, byte for byte as that code reported it."""

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
RUNS: dict[str, str] = json.loads((FIXTURES / "log-v1.runs.json").read_text())
# What the reports show differently since the fixture was written, the record being the same:
# issue 21 item 6, one word per run state in every output (an ended run, stored 'aborted', is 'ended').
# The certificates (log-v1.*.md) were regenerated for issue 24 item 4 (the test report's first page,
# the technical annex, the Instruments section of issue 22); their JSON records are as written.
# Issue 25 added the annex's basis row (the constraint the BBCOR formula assumes).
SHOWN_SINCE: dict[tuple[str, str], tuple[tuple[str, str], ...]] = {
    ("ended", "json"): (('"status": "aborted"', '"status": "ended"'),),
}


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the fixture (opening a store may touch it; the committed file stays as written)."""
    copy = tmp_path_factory.mktemp("logv1") / "log-v1.db"
    shutil.copyfile(FIXTURES / "log-v1.db", copy)
    return copy


def _report(db: Path, run_id: str, fmt: str) -> str:
    out, err = io.StringIO(), io.StringIO()
    figures = db.parent / "figures"
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["report", run_id, "--format", fmt, "--db", str(db), "--figures", str(figures)])
    assert code == 0, err.getvalue()
    return out.getvalue().replace(str(figures), "FIGURES")


def test_the_old_database_verifies(db: Path) -> None:
    with Store.open(db) as store:
        report = store.verify()
        assert report.ok, report
        assert {r.run_id: r.status for r in store.runs()} == {
            RUNS["finished"]: "finished",
            RUNS["resumed"]: "finished",
            RUNS["ended"]: "aborted",
        }


def test_the_old_runs_fold_into_their_resume_state(db: Path) -> None:
    with Store.open(db) as store:
        states = {name: fold(history(store, run_id)) for name, run_id in RUNS.items()}
        raw = {name: store.entries(run_id) for name, run_id in RUNS.items()}
    for name in ("finished", "resumed"):
        st = states[name]
        assert st.finished and st.pending is None and st.ended is None
        v = st.verdict
        assert v is not None and v.n_hits == len(v.hits) == 6
        assert v.mean == pytest.approx(statistics.fmean(v.hits), abs=1e-15)
        # guarded acceptance: PASS exactly when mean + U is at or below the limit
        assert (v.verdict == "PASS") == (v.mean + v.U <= v.limit)
        assert v.verdict == "PASS"
        requested = [e.payload["index"] for e in raw[name] if e.kind == "ShotRequested"]
        assert [s.index for s in st.shots] == requested
        assert len(st.valid_shots("valid", st.best_location_in)) == 6
    resumed = states["resumed"]
    invalid = sum(1 for e in raw["resumed"] if e.kind in ("ShotRejected", "ShotLost"))
    assert resumed.invalid_at_last_check == 11 and resumed.invalid_count == invalid
    ended = states["ended"]
    assert not ended.finished and ended.verdict is None
    assert ended.ended is not None and ended.ended.who == "Q. Manager"
    assert ended.invalid_count == 11 and ended.pending is None


@pytest.mark.parametrize("name", sorted(RUNS))
@pytest.mark.parametrize("fmt", ["json", "md"])
def test_the_old_runs_report_as_they_did(db: Path, name: str, fmt: str) -> None:
    text = _report(db, RUNS[name], fmt)
    golden = (FIXTURES / f"log-v1.{name}.{fmt}").read_text()
    for old, new in SHOWN_SINCE.get((name, fmt), ()):
        assert old in golden
        golden = golden.replace(old, new)
    if fmt == "json":
        assert json.loads(text) == json.loads(golden)
    assert text == golden
    if fmt == "md":
        headline = {
            "finished": "**PASS: BBCOR",
            "resumed": "**PASS: BBCOR",
            "ended": "Run ended without a verdict",
        }
        assert headline[name] in text


def test_the_console_and_the_report_show_what_the_one_fold_says(db: Path) -> None:
    from rig.report.record import run_record
    from rig.tui.live import LiveRun

    with Store.open(db) as store:
        for run_id in RUNS.values():
            events = history(store, run_id)
            st, record, live = fold(events), run_record(store, run_id), LiveRun()
            for e in events:
                live.apply(e)
            statuses = {s.index: s.status for s in st.shots}
            assert statuses == {s["index"]: s["status"] for s in record["shots"]}
            assert statuses == {i: s.status for i, s in live.shots.items()}
            # one shot record: the console's shots are the fold's entries, which the report renders
            assert all(s.entry is live.run.by_index[i] for i, s in live.shots.items())
            assert live.run == st and live.verdict == st.verdict
            verdict = st.verdict and {k: v for k, v in st.verdict.to_payload().items() if k != "cross_check"}
            assert record["verdict"] == verdict
            assert live.best_location_in == st.best_location_in
            assert [i["kind"] for i in record["interruptions"]] == [n.kind for n in st.stops]
