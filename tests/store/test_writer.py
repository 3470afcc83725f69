"""A run's entries go to the store at commit points (rig.store.RunWriter): held entries are written
with the next commit point, in order, in one transaction; what the store would refuse is refused
when it is recorded; and in a certification the shot's intent is on disk before FIRE, its raw
record, traffic and outcome in one transaction (issue 26)."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.protocols.control import ASKED, SCRIPT
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.store import RecordRefused, RunWriter, Store, StoreError
from tests.e2e.procs import SAMPLE_BAT


def on_disk(db: Path) -> list[str]:
    """The log's kinds as another process would read them now (a connection of its own)."""
    conn = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        return [kind for (kind,) in conn.execute("SELECT kind FROM log ORDER BY seq")]
    finally:
        conn.close()


def new_run(tmp_path: Path) -> tuple[Store, str, Path]:
    db = tmp_path / "r.db"
    store = Store.open(db)
    store.register_bat("B-1", {})
    return store, store.create_run("bbcor", "B-1", {}), db


def test_held_entries_go_with_the_next_commit_point_in_order(tmp_path: Path) -> None:
    store, run_id, db = new_run(tmp_path)
    with store:
        writer = RunWriter(store, run_id)
        before = on_disk(db)
        assert writer.record("LocationSet", {"at": 1}, commit=False) == []
        assert writer.record("OperatorPrompted", {"p": 2}, commit=False) == []
        assert on_disk(db) == before and writer.held == 2  # nothing written yet
        written = writer.record("ShotRequested", {"index": 1})
        assert [e.kind for e in written] == ["LocationSet", "OperatorPrompted", "ShotRequested"]
        assert on_disk(db) == [*before, "LocationSet", "OperatorPrompted", "ShotRequested"]
        assert writer.held == 0 and writer.commit() == []  # nothing left to write
        assert store.verify().ok


def test_what_the_store_would_refuse_is_refused_when_recorded(tmp_path: Path) -> None:
    store, run_id, _ = new_run(tmp_path)
    with store:
        writer = RunWriter(store, run_id)
        writer.record("LocationSet", {"at": 1}, commit=False)
        with pytest.raises(RecordRefused, match=r"payload\.speed = nan"):
            writer.record("ShotFired", {"speed": float("nan")}, commit=False)
        with pytest.raises(RecordRefused, match="written by the store itself"):
            writer.record("RunStatusChanged", {"status": "finished"}, commit=False)
        with pytest.raises(RecordRefused, match="kind"):
            writer.record("not a kind", {}, commit=False)
        assert writer.held == 1  # the refused ones were never held; the good one still is
        payload: dict[str, Any] = {"at": [1, 2]}
        writer.record("ScanExtended", payload, commit=False)
        payload["at"].append(3)  # the caller's dict changes after it was recorded
        written = writer.commit()
        assert [e.kind for e in written] == ["LocationSet", "ScanExtended"]
        assert written[1].payload == {"at": [1, 2]}


def test_a_failed_commit_writes_nothing_and_lets_its_entries_go(tmp_path: Path) -> None:
    """As a crash there would: nothing half-written, nothing written twice by a later commit."""
    store, run_id, db = new_run(tmp_path)
    with store:
        writer = RunWriter(store, run_id)
        writer.record("LocationSet", {"at": 1}, commit=False)
        store.set_run_status(run_id, "aborted")  # sealed meanwhile: the store refuses the run's entries
        before = on_disk(db)
        with pytest.raises(RecordRefused, match="sealed"):
            writer.record("ShotRequested", {"index": 1})
        assert writer.held == 0 and on_disk(db) == before  # all or none: none
        writer.record("LocationSet", {"at": 2}, commit=False)
    with pytest.raises(StoreError, match="closed"):
        writer.commit()
    assert writer.held == 0 and on_disk(db) == before


def test_which_events_are_commit_points() -> None:
    """The intent before FIRE, a shot's outcome, a measurement, a person's answer, a run's end commit;
    a start, a location, a prompt, a scripted answer and the shot's raw record and traffic wait."""
    waits = sorted(kind for kind, cls in ev.BY_KIND.items() if cls.persisted and cls.WAITS)
    assert waits == [
        "BallReplaced",
        "EnvironmentChecked",
        "LocationChosen",
        "LocationSet",
        "OperatorPrompted",
        "RunResumed",
        "RunStarted",
        "ScanExtended",
        "ShotFired",
        "Traffic",
    ]
    for kind in ("ShotRequested", "ShotLost", "MoiMeasured", "InstrumentsIdentified", "RunInterrupted"):
        assert not ev.BY_KIND[kind].WAITS, kind
    assert ev.OperatorAnswered(prompt_id="ring", answer=True, given=ASKED).commits
    assert ev.OperatorAnswered(prompt_id="ring", answer=True).commits  # not said how: kept at once
    assert not ev.OperatorAnswered(prompt_id="ring", answer=True, given=SCRIPT).commits


def test_a_certification_commits_the_intent_before_fire_and_each_shot_whole(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    seen: list[tuple[str, list[str]]] = []

    def watch(event: ev.RunEvent) -> None:  # what another reader finds on disk as each event goes by
        if event.kind in ("ShotRequested", "ShotFired"):
            seen.append((event.kind, on_disk(db)))

    batches: list[list[str]] = []
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(db) as store:
        append_many = store.append_many

        def spy(items: Any) -> Any:
            items = list(items)
            batches.append([kind for _, kind, _ in items])
            return append_many(items)

        store.append_many = spy  # type: ignore[method-assign]
        out = certify(store, Procedure.load("bbcor"), bat, sim_config("ideal", bat=bat), subscribers=[watch])
        assert out.status == "finished" and store.verify().ok
        entries = store.entries(out.run_id)
    for kind, disk in seen:
        if kind == "ShotRequested":
            assert disk[-1] == "ShotRequested"  # the intent is on disk before FIRE
        else:
            assert disk[-1] != "ShotFired"  # the raw record is held until its outcome
    shots = [b for b in batches if "ShotFired" in b]
    assert shots and all(b == ["ShotFired", "Traffic", "ShotMeasured"] for b in shots), shots
    assert all(b[-1] == "ShotRequested" for b in batches if "ShotRequested" in b)
    n_shots = sum(e.kind == "ShotRequested" for e in entries)
    assert len(batches) <= 2 * n_shots + 4  # per shot its intent and its whole; a few for start and end
    assert sum(len(b) for b in batches) == sum(
        e.kind not in ("RunCreated", "RunStatusChanged") for e in entries
    )  # every entry of the run went through the writer, once
