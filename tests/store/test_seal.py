"""A closed run is sealed; each run's shot numbers are used once: what verify and reports make of it.

The forgeries here are written as a forger would: plain sqlite3, append-only triggers lifted, and
every hash computed by hand from the published formula (not with the store's own code).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.cli import main
from rig.report.record import run_record
from rig.store import Anchor, RecordRefused, Store
from tests.store.conftest import raw


def forge_append(
    path: Path, run_id: str, kind: str, payload: dict[str, object], t_utc: str
) -> tuple[int, str]:
    """Append one correctly chained row behind the store's back; returns its (seq, hash)."""
    with raw(path) as db:
        seq, prev = db.execute("SELECT seq, hash FROM log ORDER BY seq DESC LIMIT 1").fetchone()
        text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
        material = json.dumps([prev, seq + 1, run_id, kind, t_utc, text], separators=(",", ":"))
        digest = hashlib.sha256(material.encode()).hexdigest()
        db.execute(
            "INSERT INTO log (seq, run_id, kind, payload, t_utc, prev_hash, hash) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (seq + 1, run_id, kind, text, t_utc, prev, digest),
        )
        return seq + 1, digest


@pytest.fixture
def finished(tmp_path: Path) -> Iterator[tuple[Path, str, Anchor]]:
    """A store holding one run that failed and was closed; yields (path, run id, its seal)."""
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        store.register_bat("B-1", {"model": "X"})
        run = store.create_run("bbcor", "B-1", {})
        store.append(run, "RunStarted", {"procedure": {}, "bat": {}, "rig": {}})
        for i in (1, 2):
            store.append(run, "ShotRequested", {"index": i, "purpose": "valid", "location_in": 6.0})
            store.append(run, "ShotFired", {"index": i, "crossings": []})
            store.append(run, "ShotMeasured", {"index": i, "metric": 0.51, "u": 0.001})
        store.append(run, "RunFinished", {"verdict": "FAIL", "mean": 0.51, "n_hits": 2})
        seal = store.set_run_status(run, "finished", "FAIL")
    yield path, run, Anchor(seal.seq, seal.hash)


def forge_pass(path: Path, run: str) -> list[int]:
    """The forgery of the finding: a PASS verdict and a status change after the run's seal."""
    a, _ = forge_append(
        path,
        run,
        "RunFinished",
        {"verdict": "PASS", "mean": 0.49, "n_hits": 2},
        "2030-01-01T00:00:00.000000+00:00",
    )
    b, _ = forge_append(
        path,
        run,
        "RunStatusChanged",
        {"status": "finished", "verdict": "PASS"},
        "2030-01-01T00:00:01.000000+00:00",
    )
    with raw(path) as db:  # and the convenience table, so that it agrees with the forged tail
        db.execute("UPDATE runs SET verdict = 'PASS', last_seq = ? WHERE run_id = ?", (b, run))
        db.commit()
    return [a, b]


def test_the_store_refuses_appends_to_a_closed_run(finished: tuple[Path, str, Anchor]) -> None:
    path, run, seal = finished
    with Store.open(path, chain_format=1) as store:
        for kind in ("RunFinished", "Note"):
            with pytest.raises(RecordRefused, match=f"finished and sealed at seq {seal.seq}: no {kind}"):
                store.append(run, kind, {"verdict": "PASS"})
        with pytest.raises(RecordRefused, match="already finished"):
            store.set_run_status(run, "finished", "PASS")
        assert store.head() == seal  # nothing was written
        other = store.create_run("bbcor", "B-1", {})
        store.set_run_status(other, "aborted")
        with pytest.raises(RecordRefused, match="aborted and sealed"):
            store.append(other, "ShotFired", {"index": 1})
        assert store.verify([seal]).ok


def test_verify_reports_a_verdict_forged_after_the_seal(
    finished: tuple[Path, str, Anchor], capsys: pytest.CaptureFixture[str]
) -> None:
    path, run, seal = finished
    forged = forge_pass(path, run)
    with Store.open(path, chain_format=1) as store:
        report = store.verify([seal])  # the certificate's anchor still matches its own entry
    assert not report.ok
    assert report.first_broken_seq is None  # the chain itself links: only the seal catches it
    after_seal = [p for p in report.problems if "after it was sealed" in p]
    assert [int(p.split(":")[0].removeprefix("seq ")) for p in after_seal] == forged
    assert all(f"sealed at seq {seal.seq}" in p for p in after_seal)
    assert main(["verify", "--db", str(path), "--anchor", f"{seal.seq}:{seal.hash}"]) == 1
    out = capsys.readouterr().out
    assert out.startswith("ALTERED") and f"seq {forged[0]}: RunFinished appended to run {run}" in out


def test_a_report_shows_only_what_the_seal_covers(
    finished: tuple[Path, str, Anchor], capsys: pytest.CaptureFixture[str]
) -> None:
    path, run, seal = finished
    forged = forge_pass(path, run)
    with Store.open(path, chain_format=1) as store:
        record = run_record(store, run)
    assert record["verdict"]["verdict"] == "FAIL" and record["verdict"]["mean"] == 0.51  # the real one
    assert record["status"] == "finished"
    assert record["anchor"] == {"seq": seal.seq, "hash": seal.hash}  # the certificate's anchor
    assert record["entries"] == seal.seq - 1  # every entry up to the seal but the bat's
    cov = record["coverage"]
    assert cov["by"] == "seal" and cov["upto_seq"] == seal.seq
    assert [e["seq"] for e in cov["left_out"]] == forged
    assert "after the seal" in cov["text"] and "not part of this record" in cov["text"]
    assert main(["report", run, "--db", str(path), "--format", "md"]) == 0
    out, err = capsys.readouterr()
    assert "PASS" not in out.split("Record anchor")[0]  # the forged verdict is nowhere on it
    assert "not part of this record" in out and "not part of this record" in err


def test_a_report_as_far_as_an_anchor(
    finished: tuple[Path, str, Anchor], capsys: pytest.CaptureFixture[str]
) -> None:
    path, run, _ = finished
    with Store.open(path, chain_format=1) as store:
        first_shot = store.entries(run, kinds=["ShotMeasured"])[0]
        record = run_record(store, run, Anchor(first_shot.seq, first_shot.hash))
    assert record["status"] == "running" and record["verdict"] is None
    assert [s["index"] for s in record["shots"]] == [1]
    assert record["coverage"]["by"] == "anchor" and len(record["coverage"]["left_out"]) == 5
    wrong = f"{first_shot.seq}:{'0' * 64}"
    assert main(["report", run, "--db", str(path), "--anchor", wrong]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rewritten" in err and "Traceback" not in err


@pytest.mark.parametrize(
    "text",
    [
        "abc",
        "12",
        ":" + "a" * 64,
        "x:" + "a" * 64,
        "0:" + "a" * 64,
        "5:xyz",
        "5:" + "g" * 64,
        "9" * 30 + ":" + "a" * 64,
    ],
)
def test_a_malformed_anchor_is_one_clear_line(
    finished: tuple[Path, str, Anchor], capsys: pytest.CaptureFixture[str], text: str
) -> None:
    path, run, _ = finished
    assert main(["verify", "--db", str(path), "--anchor", text]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "expected SEQ:HASH" in err and "Traceback" not in err
    assert main(["report", run, "--db", str(path), "--anchor", text]) == 2
    assert "expected SEQ:HASH" in capsys.readouterr().err


def test_verify_flags_a_shot_number_used_twice(store: Store) -> None:
    store.register_bat("B-1", {})
    run, other = store.create_run("bbcor", "B-1", {}), store.create_run("bbcor", "B-1", {})
    seqs: dict[tuple[str, int], list[int]] = {}
    # Two runners resuming one run after shot 1: both request and fire shot 2 and finish.
    script = [
        (run, "ShotRequested", 1),
        (run, "ShotFired", 1),
        (other, "ShotRequested", 1),
        (other, "ShotFired", 1),
    ]
    script += [
        (run, "ShotRequested", 2),
        (run, "ShotRequested", 2),
        (run, "ShotFired", 2),
        (run, "ShotFired", 2),
    ]
    for run_id, kind, index in script:
        entry = store.append(run_id, kind, {"index": index, "purpose": "valid"})
        seqs.setdefault((kind, index), []).append(entry.seq)
    first_verdict = store.append(run, "RunFinished", {"verdict": "PASS"}).seq
    second_verdict = store.append(run, "RunFinished", {"verdict": "FAIL"}).seq
    report = store.verify()
    assert not report.ok and report.first_broken_seq is None
    requested, fired = seqs[("ShotRequested", 2)], seqs[("ShotFired", 2)]
    why = "two runners at once?"
    assert list(report.problems) == [
        f"seq {requested[1]}: run {run}: shot 2 requested twice (the first at seq {requested[0]}; {why})",
        f"seq {fired[1]}: run {run}: shot 2 fired twice (the first at seq {fired[0]}; {why})",
        f"seq {second_verdict}: run {run}: a second RunFinished (the first at seq {first_verdict}; {why})",
    ]  # shot 1 in two different runs is no finding


def test_distinct_shot_numbers_verify(store: Store) -> None:
    store.register_bat("B-1", {})
    run = store.create_run("bbcor", "B-1", {})
    for index in (1, 2, 3):
        store.append(run, "ShotRequested", {"index": index})
        store.append(run, "ShotFired", {"index": index})
    store.append(run, "RunFinished", {"verdict": "PASS"})
    store.set_run_status(run, "finished", "PASS")
    assert store.verify().ok
