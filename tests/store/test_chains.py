"""Chain format 2: a hash chain per run and the lab chain of run anchors; what each detects."""

from __future__ import annotations

import hashlib
import itertools
import json
import multiprocessing
import sqlite3
from pathlib import Path

import pytest

from rig.store import Store, entry_hash
from tests.store.conftest import raw

COLS = "INSERT INTO log (seq, run_id, kind, payload, t_utc, prev_hash, hash, chain, chain_seq) "


def _fill(store: Store) -> tuple[str, str]:
    """Bat, run A (3 shots, finished), a note, run B (1 shot, open)."""
    store.register_bat("B-1", {"model": "X33"})
    run_a = store.create_run("bbcor", "B-1", {})
    for i in range(3):
        store.append(run_a, "ShotMeasured", {"shot": i})
    store.append(None, "Note", {"text": "coffee"})
    run_b = store.create_run("besr", "B-1", {})
    store.append(run_b, "ShotFired", {"shot": 0})
    store.set_run_status(run_a, "finished", "PASS")
    return run_a, run_b


def _problems(store: Store) -> str:
    report = store.verify()
    assert not report.ok
    return "\n".join(report.problems)


def test_a_clean_store_has_one_chain_per_run_and_verifies(store2: Store) -> None:
    run_a, run_b = _fill(store2)
    assert store2.verify().ok
    every = store2.entries()
    for chain in (run_a, run_b, None):
        mine = [e for e in every if e.run_id == chain]
        assert [e.chain_seq for e in mine] == list(range(1, len(mine) + 1))
        assert mine[0].prev_hash == "0" * 64
        assert all(b.prev_hash == a.hash for a, b in itertools.pairwise(mine))
    lab = [(e.kind, e.payload.get("run_id")) for e in every if e.run_id is None]
    assert lab == [
        ("BatRegistered", None),
        ("RunOpened", run_a),
        ("Note", None),
        ("RunOpened", run_b),
        ("RunSealed", run_a),
    ]
    sealed = next(e for e in every if e.kind == "RunSealed")
    last_a = [e for e in every if e.run_id == run_a][-1]
    assert sealed.payload == {
        "run_id": run_a,
        "chain_seq": last_a.chain_seq,
        "hash": last_a.hash,
        "status": "finished",
    }


def test_the_documented_formula_checks_each_chain_without_our_code(store2: Store) -> None:
    """docs/records.md: sha256 of [prev_hash, chain_seq, run_id, kind, t_utc, payload], per chain."""
    _fill(store2)
    heads: dict[str, str] = {}
    db = sqlite3.connect(store2.path)
    try:
        rows = db.execute(
            "SELECT chain, chain_seq, run_id, kind, payload, t_utc, prev_hash, hash FROM log ORDER BY seq"
        )
        for chain, n, run_id, kind, payload, t, p, h in rows:
            prev = heads.get(chain, "0" * 64)
            material = json.dumps([prev, n, run_id, kind, t, payload], separators=(",", ":"))
            assert p == prev and h == hashlib.sha256(material.encode()).hexdigest(), (chain, n)
            assert chain == (run_id or "lab")
            heads[chain] = h
    finally:
        db.close()


def test_an_edited_entry_is_named_by_its_run_and_number(store2: Store) -> None:
    run_a, _ = _fill(store2)
    target = [e for e in store2.entries(run_a) if e.kind == "ShotMeasured"][1]
    with raw(store2.path) as db:
        db.execute("UPDATE log SET payload = ? WHERE seq = ?", ('{"shot":9}', target.seq))
    report = store2.verify()
    assert report.first_broken_seq == target.seq
    assert f"run {run_a} entry {target.chain_seq}: hash mismatch" in (report.reason or "") or (
        f"run {run_a} entry {target.chain_seq}: hash mismatch" in _problems(store2)
    )


def test_a_deleted_entry_leaves_a_gap_in_its_run(store2: Store) -> None:
    run_a, _ = _fill(store2)
    target = store2.entries(run_a)[2]
    with raw(store2.path) as db:
        db.execute("DELETE FROM log WHERE seq = ?", (target.seq,))
    assert f"run {run_a}: entry {target.chain_seq} missing" in _problems(store2)


def test_a_run_deleted_whole_is_found_from_the_lab_chain(store2: Store) -> None:
    _, run_b = _fill(store2)
    with raw(store2.path) as db:
        db.execute("DELETE FROM log WHERE run_id = ?", (run_b,))
    assert f"run {run_b}: anchored in the lab chain but its entries are gone" in _problems(store2)


def test_entries_forged_after_the_seal_are_found_from_the_seal_anchor(store2: Store) -> None:
    """A verdict chained correctly onto the sealed run: the lab chain's seal says where it ended."""
    run_a, _ = _fill(store2)
    last = store2.entries(run_a)[-1]
    t, payload = "2026-01-01T00:00:00+00:00", '{"verdict":"FAIL"}'
    n = (last.chain_seq or 0) + 1
    with raw(store2.path) as db:
        db.execute(
            COLS + "VALUES (1000, ?, 'RunFinished', ?, ?, ?, ?, ?, ?)",
            (
                run_a,
                payload,
                t,
                last.hash,
                entry_hash(last.hash, n, run_a, "RunFinished", t, payload),
                run_a,
                n,
            ),
        )
    assert f"run {run_a}: 1 entries after its seal (entry {last.chain_seq})" in _problems(store2)


def test_a_run_added_from_outside_is_not_anchored(store2: Store) -> None:
    _fill(store2)
    t, payload = "2026-01-01T00:00:00+00:00", '{"procedure":"bbcor","bat_id":"B-1","meta":{}}'
    with raw(store2.path) as db:
        db.execute(
            COLS + "VALUES (2000, 'ghost', 'RunCreated', ?, ?, ?, ?, 'ghost', 1)",
            (payload, t, "0" * 64, entry_hash("0" * 64, 1, "ghost", "RunCreated", t, payload)),
        )
    assert "run ghost: not anchored in the lab chain (no RunOpened)" in _problems(store2)


def test_an_entry_moved_to_another_chain_is_caught(store2: Store) -> None:
    run_a, run_b = _fill(store2)
    target = store2.entries(run_b)[-1]
    with raw(store2.path) as db:
        db.execute("UPDATE log SET chain = ?, chain_seq = 999 WHERE seq = ?", (run_a, target.seq))
    assert f"seq {target.seq}: chain columns" in _problems(store2)


def _append_many(path: str, run_id: str, n: int) -> None:
    with Store.open(path, create=False) as store:
        for i in range(n):
            store.append(run_id, "ShotFired", {"shot": i})


@pytest.mark.usefixtures("cpu_load")
def test_two_processes_appending_to_two_runs_keep_both_chains_whole(tmp_path: Path) -> None:
    path = tmp_path / "lab.db"
    with Store.open(path) as store:
        store.register_bat("B", {})
        runs = [store.create_run("bbcor", "B", {}) for _ in range(2)]
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_append_many, args=(str(path), run, 60)) for run in runs]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    with Store.open(path, create=False) as store:
        assert store.verify().ok
        for run in runs:
            assert [e.chain_seq for e in store.entries(run)] == list(range(1, 62))


def test_one_run_verifies_on_its_own_and_its_own_tampering_is_found(store2: Store) -> None:
    run_a, run_b = _fill(store2)
    assert store2.verify_run(run_a).ok and store2.verify_run(run_b).ok
    assert store2.verify_run(run_a).entries_checked < len(store2.entries())  # its chain and the lab's
    target = store2.entries(run_b)[-1]
    with raw(store2.path) as db:
        db.execute("UPDATE log SET payload = '{}' WHERE seq = ?", (target.seq,))
    assert store2.verify_run(run_a).ok  # another run's damage is not this run's
    broken = store2.verify_run(run_b)
    assert not broken.ok and f"run {run_b} entry {target.chain_seq}: hash mismatch" in broken.problems[0]
    with raw(store2.path) as db:
        db.execute("DELETE FROM log WHERE run_id = ?", (run_a,))
    assert "anchored in the lab chain but its entries are gone" in "\n".join(
        store2.verify_run(run_a).problems
    )
