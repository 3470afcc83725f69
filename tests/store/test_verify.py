"""verify(): a clean store passes; every kind of tampering is caught at the right seq."""

from __future__ import annotations

import hashlib
import json
import sqlite3

import pytest

from rig.store import Anchor, Store, StoreError, entry_hash
from tests.store.conftest import Populated, raw

COLS = "INSERT INTO log (seq, run_id, kind, payload, t_utc, prev_hash, hash) "


def test_a_clean_store_verifies(populated: Populated) -> None:
    report = populated.store.verify()
    assert report.ok, report
    assert report.entries_checked == 10
    assert report.head == populated.store.head()
    assert report.first_broken_seq is None and report.problems == ()


def test_an_empty_store_verifies(store: Store) -> None:
    report = store.verify()
    assert report.ok and report.entries_checked == 0


def _broken_at(store: Store, seq: int, why: str) -> None:
    report = store.verify()
    assert not report.ok
    assert report.first_broken_seq == seq, report
    assert report.reason is not None and why in report.reason
    assert report.problems[0].startswith(f"seq {seq}: ")


def test_edited_payload(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("UPDATE log SET payload = ? WHERE seq = 4", ('{"shot":1,"v_in_m_s":71.1}',))
    _broken_at(populated.store, 4, "hash mismatch")


def test_edited_kind(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("UPDATE log SET kind = 'ShotRejected' WHERE seq = 5")
    _broken_at(populated.store, 5, "hash mismatch")


def test_edit_with_the_row_rehashed_breaks_the_next_link(populated: Populated) -> None:
    e = populated.store.entries()[3]  # seq 4
    forged = '{"shot":1,"v_in_m_s":71.1}'
    with raw(populated.store.path) as db:
        db.execute(
            "UPDATE log SET payload = ?, hash = ? WHERE seq = 4",
            (forged, entry_hash(e.prev_hash, 4, e.run_id, e.kind, e.t_utc, forged)),
        )
    _broken_at(populated.store, 5, "prev_hash mismatch")


def test_deleted_row(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("DELETE FROM log WHERE seq = 6")
    _broken_at(populated.store, 7, "seq 6 missing")


def test_deleted_first_row(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("DELETE FROM log WHERE seq = 1")
    _broken_at(populated.store, 2, "seq 1 missing")


def test_deleted_and_renumbered_rows(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("DELETE FROM log WHERE seq IN (4, 5)")
        db.execute("UPDATE log SET seq = seq - 2 WHERE seq > 5")
    _broken_at(populated.store, 4, "prev_hash mismatch")


def test_swapped_pair(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("UPDATE log SET seq = -1 WHERE seq = 4")
        db.execute("UPDATE log SET seq = 4 WHERE seq = 5")
        db.execute("UPDATE log SET seq = 5 WHERE seq = -1")
    _broken_at(populated.store, 4, "out of place: its hash places it at seq 5")


def test_inserted_row_with_a_valid_hash(populated: Populated) -> None:
    before = populated.store.entries()[4]  # seq 5: the forged row goes right after it, as seq 6
    run, t, payload = before.run_id, before.t_utc, '{"shot":99,"v_in_m_s":60.0}'
    with raw(populated.store.path) as db:
        db.execute("UPDATE log SET seq = seq + 1000 WHERE seq >= 6")
        db.execute("UPDATE log SET seq = seq - 999 WHERE seq >= 1006")
        db.execute(
            COLS + "VALUES (6, ?, 'ShotMeasured', ?, ?, ?, ?)",
            (run, payload, t, before.hash, entry_hash(before.hash, 6, run, "ShotMeasured", t, payload)),
        )
    _broken_at(populated.store, 7, "out of place: its hash places it at seq 6")


def test_row_appended_behind_the_stores_back(populated: Populated) -> None:
    head = populated.store.head()
    with raw(populated.store.path) as db:
        db.execute(
            COLS + "VALUES (11, NULL, 'Note', '{}', '2026-01-01T00:00:00+00:00', ?, ?)",
            (head.hash, "f" * 64),
        )
    _broken_at(populated.store, 11, "hash mismatch")


def test_invalid_utf8_and_blob_payloads_are_reported_not_raised(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("UPDATE log SET payload = CAST(? AS TEXT) WHERE seq = 3", (b'{"shot":\xff}',))
        db.execute("UPDATE log SET payload = CAST(payload AS BLOB) WHERE seq = 9")
    report = populated.store.verify()
    assert report.first_broken_seq == 3 and "UTF-8" in str(report.reason)
    assert any(p.startswith("seq 9: payload is stored as blob") for p in report.problems)
    with pytest.raises(StoreError):
        populated.store.entries()


def test_later_independent_breaks_are_listed_too(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute("UPDATE log SET kind = 'X' WHERE seq IN (3, 8)")
    report = populated.store.verify()
    assert report.first_broken_seq == 3
    assert [p.split(":")[0] for p in report.problems[:2]] == ["seq 3", "seq 8"]


def test_tampered_runs_table(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute(
            "UPDATE runs SET verdict = 'pass', status = 'finished' WHERE run_id = ?", (populated.run_b,)
        )
    report = populated.store.verify()
    assert not report.ok and report.first_broken_seq is None  # the chain itself is intact
    assert (
        f"table runs, row {populated.run_b}: status is 'finished', the log says 'running'" in report.problems
    )


def test_tampered_bats_table(populated: Populated) -> None:
    with raw(populated.store.path) as db:
        db.execute('UPDATE bats SET spec = \'{"model":"X34"}\'')
        db.execute("INSERT INTO bats VALUES ('B-9', '{}')")
    problems = populated.store.verify().problems
    assert any(p.startswith("table bats, row B-1: spec is") for p in problems)
    assert "table bats: row B-9 is not in the log" in problems


def test_rebuild_indexes_reproduces_the_tables(populated: Populated) -> None:
    store = populated.store
    runs, bats = store.runs(), store.bats()
    with raw(store.path) as db:
        db.execute("DELETE FROM runs")
        db.execute("UPDATE bats SET spec = '{}'")
    assert not store.verify().ok
    store.rebuild_indexes()
    assert store.runs() == runs and store.bats() == bats
    assert store.verify().ok


def test_rebuild_refuses_a_log_that_contradicts_itself(populated: Populated) -> None:
    head = populated.store.head()
    with raw(populated.store.path) as db:
        t, payload = "2026-01-01T00:00:00+00:00", "{}"
        db.execute(
            COLS + "VALUES (11, 'ghost', 'ShotFired', ?, ?, ?, ?)",
            (payload, t, head.hash, entry_hash(head.hash, 11, "ghost", "ShotFired", t, payload)),
        )
    with pytest.raises(StoreError, match="run ghost, which was never created"):
        populated.store.rebuild_indexes()
    assert "seq 11: entry of run ghost, which was never created" in populated.store.verify().problems


def test_truncated_tail_needs_the_outside_anchor(populated: Populated) -> None:
    store = populated.store
    anchor = store.head()  # e.g. printed on the certificate
    with raw(store.path) as db:
        db.execute("DELETE FROM log WHERE seq = 10")
        db.execute(
            "UPDATE runs SET status = 'running', verdict = NULL, last_seq = 6 WHERE run_id = ?",
            (populated.run_a,),
        )
    # Honest limit: a cleanly cut tail is a valid shorter chain.
    assert store.verify().ok
    report = store.verify(anchors=[anchor])
    assert not report.ok and "anchor seq 10: no such entry" in report.problems[0]


def test_rewritten_chain_is_caught_by_the_anchor(populated: Populated) -> None:
    store = populated.store
    anchor = store.head()
    with raw(store.path) as db:  # rewrite seq 10 and re-hash it: the chain alone cannot tell
        e = store.entries()[-1]
        payload = '{"status":"finished","verdict":"fail"}'
        db.execute(
            "UPDATE log SET payload = ?, hash = ? WHERE seq = 10",
            (payload, entry_hash(e.prev_hash, 10, e.run_id, e.kind, e.t_utc, payload)),
        )
        db.execute("UPDATE runs SET verdict = 'fail' WHERE run_id = ?", (populated.run_a,))
    assert store.verify().ok
    assert "the log was rewritten" in store.verify([Anchor(anchor.seq, anchor.hash)]).problems[0]


def test_the_log_refuses_sql_edits_and_missing_guards_are_reported(populated: Populated) -> None:
    db = sqlite3.connect(populated.store.path, isolation_level=None)
    with pytest.raises(sqlite3.IntegrityError, match="append-only"):
        db.execute("UPDATE log SET kind = 'X' WHERE seq = 3")
    with pytest.raises(sqlite3.IntegrityError, match="append-only"):
        db.execute("DELETE FROM log WHERE seq = 10")
    db.execute("DROP TRIGGER log_no_delete")
    db.close()
    report = populated.store.verify()
    assert report.problems == ("append-only triggers removed: log_no_delete",)


def test_the_documented_formula_checks_the_file_without_our_code(populated: Populated) -> None:
    # docs/records.md promises auditors this recipe; it must keep matching what the store writes.
    populated.store.append(None, "Note", {"text": "é ☃\n", "x": [1.5, None]})
    prev = "0" * 64
    db = sqlite3.connect(populated.store.path)
    try:
        rows = db.execute("SELECT seq, run_id, kind, payload, t_utc, prev_hash, hash FROM log ORDER BY seq")
        for seq, run_id, kind, payload, t, p, h in rows:
            material = json.dumps([prev, seq, run_id, kind, t, payload], separators=(",", ":"))
            assert p == prev and h == hashlib.sha256(material.encode()).hexdigest(), seq
            prev = h
    finally:
        db.close()
    assert prev == populated.store.head_hash()
