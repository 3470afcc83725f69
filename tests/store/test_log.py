"""Writing and reading the log: round trips, canonical JSON, runs, bats and refusals."""

from __future__ import annotations

import dataclasses
import itertools
import json
from datetime import UTC, datetime

import pytest

from rig.core.errors import RigError
from rig.store import (
    GENESIS_HASH,
    RecordRefused,
    Store,
    StoreError,
    UnknownRecord,
    canonical_json,
    decode_bytes,
    encode_bytes,
    entry_hash,
)
from tests.store.conftest import Populated


def test_append_then_read_back(store: Store) -> None:
    store.register_bat("B-1", {"length_in": 33})
    run = store.create_run("bbcor", "B-1", {"operator": "ann"})
    payload = {"shot": 3, "speeds": [61.2, -0.5, 1e-300], "ok": True, "note": "été ☃", "none": None}
    written = store.append(run, "ShotMeasured", payload)
    [read] = store.entries(run, kinds=["ShotMeasured"])
    assert read == written
    assert read.payload == payload
    assert (read.seq, read.run_id, read.kind) == (3, run, "ShotMeasured")
    assert read.time.tzinfo is not None
    with pytest.raises(dataclasses.FrozenInstanceError):
        read.kind = "Other"  # type: ignore[misc]


def test_entries_chain_and_filter(populated: Populated) -> None:
    store = populated.store
    every = store.entries()
    assert [e.seq for e in every] == list(range(1, 11))
    assert every[0].prev_hash == GENESIS_HASH
    assert all(b.prev_hash == a.hash for a, b in itertools.pairwise(every))
    assert [e.seq for e in store.entries(populated.run_a)] == [2, 3, 4, 5, 6, 10]
    assert [e.seq for e in store.entries(kinds=["Note", "ShotFired"])] == [7, 9]
    assert [e.seq for e in store.entries(populated.run_a, after_seq=5)] == [6, 10]
    assert store.entries(kinds=[]) == []


def test_a_returned_append_is_visible_to_another_connection(store: Store) -> None:
    entry = store.append(None, "Note", {"n": 1})
    with Store.open(store.path, create=False) as other:
        assert other.entries() == [entry]
        assert other.head_hash() == entry.hash


def test_canonical_json_is_one_fixed_text() -> None:
    a = {"b": [1, 2.5, None], "a": {"y": True, "x": "é"}}
    b = {"a": {"x": "é", "y": True}, "b": (1, 2.5, None)}
    text = canonical_json(a)
    assert text == canonical_json(b) == '{"a":{"x":"\\u00e9","y":true},"b":[1,2.5,null]}'
    assert json.loads(text) == {**a, "b": [1, 2.5, None]}
    assert canonical_json({"f": 0.1}) == '{"f":0.1}'  # shortest repr, no float noise


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ({"x": float("nan")}, "payload.x"),
        ({"x": [1, float("inf")]}, "payload.x[1]"),
        ({"x": b"\x00"}, "encode_bytes"),
        ({1: "a"}, "key 1"),
        ({"x": {1, 2}}, "set"),
    ],
)
def test_canonical_json_refuses_what_it_cannot_round_trip(value: object, fragment: str) -> None:
    with pytest.raises(RecordRefused, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        canonical_json(value)


def test_entry_hash_fields_cannot_slide_into_each_other() -> None:
    base = entry_hash(GENESIS_HASH, 1, None, "AB", "t", "{}")
    assert base != entry_hash(GENESIS_HASH, 1, None, "A", "Bt", "{}")
    assert base != entry_hash(GENESIS_HASH, 1, "", "AB", "t", "{}")
    assert base != entry_hash(GENESIS_HASH, 11, None, "AB", "t", "{}")


def test_bytes_helpers_round_trip_and_refuse_junk() -> None:
    data = bytes(range(256))
    assert decode_bytes(encode_bytes(data)) == data
    assert encode_bytes(b"\x02V?\r\n") == "AlY/DQo="
    with pytest.raises(RecordRefused, match="base64"):
        decode_bytes("not base64!")


def test_runs_status_and_resume_view(populated: Populated) -> None:
    store, a, b = populated.store, populated.run_a, populated.run_b
    assert [r.run_id for r in store.runs()] == [a, b]
    assert store.run(a).status == "finished" and store.run(a).verdict == "pass"
    assert store.run(a).last_seq == 10 and store.run(b).last_seq == 9
    assert [r.run_id for r in store.open_runs()] == [b]
    change = store.set_run_status(b, "aborted")
    assert (change.kind, change.payload) == ("RunStatusChanged", {"status": "aborted", "verdict": None})
    assert store.open_runs() == []
    with pytest.raises(RecordRefused, match="already aborted"):
        store.set_run_status(b, "finished", "pass")
    with pytest.raises(RecordRefused, match="status 'running'"):
        store.set_run_status(a, "running")


def test_created_run_starts_at_its_created_entry(store: Store) -> None:
    stamp = datetime(2026, 3, 1, 12, 0, tzinfo=UTC)
    with Store.open(store.path, clock=lambda: stamp) as s:
        s.register_bat("B-1", {})
        run = s.create_run("besr", "B-1", {"k": [1]})
        [created] = s.entries(run)
    assert len(run) == 32 and int(run, 16) >= 0
    assert created.kind == "RunCreated"
    assert created.payload == {"procedure": "besr", "bat_id": "B-1", "meta": {"k": [1]}}
    assert store.run(run).started_utc == created.t_utc == "2026-03-01T12:00:00.000000+00:00"


def test_unknown_run_names_the_known_ones(populated: Populated) -> None:
    store = populated.store
    with pytest.raises(UnknownRecord, match=f"no run 'nope'; known runs: .*{populated.run_a}") as info:
        store.run("nope")
    assert isinstance(info.value, StoreError) and isinstance(info.value, RigError)
    with pytest.raises(UnknownRecord, match=f"did you mean {populated.run_b}"):
        store.run(populated.run_b[:8])
    with pytest.raises(UnknownRecord, match="no run 'nope'"):
        store.append("nope", "ShotFired", {})


def test_bats_are_registered_once(store: Store) -> None:
    store.register_bat("B-1", {"drop": -3})
    assert store.bats() == {"B-1": {"drop": -3}}
    with pytest.raises(RecordRefused, match="already registered"):
        store.register_bat("B-1", {"drop": -5})
    with pytest.raises(UnknownRecord, match="no bat 'B-2'; known bats: B-1"):
        store.create_run("bbcor", "B-2", {})


@pytest.mark.parametrize(
    ("kind", "payload", "fragment"),
    [
        ("RunCreated", {}, "written by the store itself"),
        ("RunStatusChanged", {}, "written by the store itself"),
        ("Shot Fired", {}, "kind 'Shot Fired'"),
        ("", {}, "kind ''"),
        ("ShotFired", [1, 2], "payload must be a dict"),
        ("ShotFired", {"t": float("nan")}, "NaN"),
    ],
)
def test_refused_entries_write_nothing(
    populated: Populated, kind: str, payload: object, fragment: str
) -> None:
    store = populated.store
    before = store.head()
    with pytest.raises(RecordRefused, match=fragment):
        store.append(populated.run_b, kind, payload)  # type: ignore[arg-type]
    assert store.head() == before


def test_append_many_is_all_or_nothing(populated: Populated) -> None:
    store, run = populated.store, populated.run_b
    written = store.append_many([(run, "Traffic", {"i": i}) for i in range(3)])
    assert [e.seq for e in written] == [11, 12, 13]
    assert store.run(run).last_seq == 13
    with pytest.raises(RecordRefused):
        store.append_many([(run, "Traffic", {"i": 4}), (run, "Traffic", {"bad": float("inf")})])
    with pytest.raises(UnknownRecord):
        store.append_many([(run, "Traffic", {"i": 4}), ("gone", "Traffic", {})])
    assert store.head().seq == 13 and store.verify().ok


def test_head_of_an_empty_store_is_genesis(store: Store) -> None:
    assert store.head_hash() == GENESIS_HASH and store.head().seq == 0
    entry = store.append(None, "Note", {})
    assert store.head_hash() == entry.hash


def test_a_closed_store_says_so(store: Store) -> None:
    store.close()
    store.close()
    with pytest.raises(StoreError, match="closed"):
        store.entries()


def test_resume_after_reopen_replays_in_order(populated: Populated) -> None:
    path, run = populated.store.path, populated.run_b
    populated.store.append(run, "ShotFired", {"shot": 1})
    populated.store.close()
    with Store.open(path, create=False) as again:
        [open_run] = again.open_runs()
        assert open_run.run_id == run
        replay = again.entries(run)
        assert [e.kind for e in replay] == ["RunCreated", "ShotFired", "ShotFired"]
        assert [e.payload.get("shot") for e in replay[1:]] == [0, 1]
        assert again.append(run, "ShotFired", {"shot": 2}).seq == replay[-1].seq + 1
