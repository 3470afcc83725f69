"""Hypothesis: any appends verify and read back; any single-byte change to a payload is caught."""

from __future__ import annotations

import sqlite3
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.store import RESERVED_KINDS, Store
from tests.store.conftest import raw

_scalars = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=12)
)
_values = st.recursive(
    _scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=10,
)
payloads = st.dictionaries(st.text(max_size=6), _values, max_size=5)
kinds = st.from_regex(r"[A-Za-z][A-Za-z0-9_.]{0,10}", fullmatch=True).filter(
    lambda k: k not in RESERVED_KINDS
)
# (in the run or rig-level, kind, payload, batched with the previous one)
appends = st.lists(st.tuples(st.booleans(), kinds, payloads, st.booleans()), min_size=1, max_size=12)


@contextmanager
def _fresh_store(chain_format: int = 2) -> Iterator[Store]:
    # Hypothesis reruns the test body many times: one folder per example, not one per test.
    with (
        tempfile.TemporaryDirectory() as folder,
        Store.open(Path(folder) / "p.db", chain_format=chain_format) as store,
    ):
        yield store


def _write(store: Store, plan: list[tuple[bool, str, dict[str, Any], bool]]) -> list[dict[str, Any]]:
    store.register_bat("B", {})
    run = store.create_run("bbcor", "B", {})
    batch: list[tuple[str | None, str, dict[str, Any]]] = []
    for in_run, kind, payload, batched in plan:
        if batch and not batched:
            store.append_many(batch)
            batch = []
        batch.append((run if in_run else None, kind, payload))
    store.append_many(batch)
    return [{"procedure": "bbcor", "bat_id": "B", "meta": {}}] + [p for _, _, p, _ in plan]


@pytest.mark.parametrize("chain_format", [1, 2])
@given(plan=appends)
def test_any_appends_verify_and_read_back(
    chain_format: int, plan: list[tuple[bool, str, dict[str, Any], bool]]
) -> None:
    with _fresh_store(chain_format) as store:
        expected = _write(store, plan)
        report = store.verify()
        assert report.ok, report
        every = store.entries()
        assert [e.seq for e in every] == list(range(1, len(every) + 1))
        entries = [e for e in every if e.kind != "RunOpened"]  # format 2: the lab chain's run anchor
        assert len(every) - len(entries) == (chain_format == 2)
        assert [e.payload for e in entries[1:]] == expected
        assert [e.kind for e in entries[2:]] == [k for _, k, _, _ in plan]
        if chain_format == 2:  # each chain numbered from 1 in append order
            for chain in {e.run_id for e in every}:
                assert [e.chain_seq for e in every if e.run_id == chain] == list(
                    range(1, sum(e.run_id == chain for e in every) + 1)
                )


@given(plan=appends, data=st.data())
def test_any_single_byte_change_in_a_payload_is_caught(
    plan: list[tuple[bool, str, dict[str, Any], bool]], data: st.DataObject
) -> None:
    with _fresh_store() as store:
        _write(store, plan)
        entries = store.entries()
        seq = data.draw(st.integers(1, len(entries)), label="seq")
        with raw(store.path) as db:
            text = db.execute("SELECT CAST(payload AS BLOB) FROM log WHERE seq = ?", (seq,)).fetchone()[0]
            at = data.draw(st.integers(0, len(text) - 1), label="byte")
            changed = bytearray(text)
            changed[at] = (changed[at] + data.draw(st.integers(1, 255), label="delta")) % 256
            # Stored as TEXT even when it is no longer valid UTF-8, as a hex editor would leave it.
            db.execute("UPDATE log SET payload = CAST(? AS TEXT) WHERE seq = ?", (bytes(changed), seq))
        report = store.verify()
        assert not report.ok
        assert report.first_broken_seq == seq, report


def test_byte_change_helper_really_changes_the_stored_text(tmp_path: Path) -> None:
    # Guards the property above against a tamper step that silently does nothing.
    with Store.open(tmp_path / "p.db") as store:
        store.append(None, "Note", {"a": 1})
        with raw(store.path) as db:
            db.execute("UPDATE log SET payload = CAST(? AS TEXT) WHERE seq = 1", (b'{"a":2}',))
        check = sqlite3.connect(store.path)
        try:
            assert check.execute("SELECT payload, typeof(payload) FROM log").fetchone() == ('{"a":2}', "text")
        finally:
            check.close()
