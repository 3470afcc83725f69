"""The typed events and the log: every kind round trips through the store's JSON and back, and
the log format 1 fixture's entries parse into the typed classes."""

from __future__ import annotations

import json
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core import events as ev
from rig.store import Store

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "log-v1.db"

_scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(2**53), 2**53)
    | st.floats(allow_nan=False, allow_infinity=False)
)
_json = st.recursive(
    _scalars | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=8,
)


def _typed(cls: type) -> list[Any]:
    """The payload's typed fields of an event class: its own, and its record's, written flat."""
    own = [f for f in fields(cls) if f.name not in ("extra", cls.RECORD)]
    record = ev.RECORDS.get(cls)
    return own + ([f for f in fields(record) if f.name not in ("rest", "read")] if record else [])


@st.composite
def payloads(draw: st.DrawFn, kind: str) -> dict[str, Any]:
    """A payload of `kind`: each typed field some JSON value, plus untyped keys."""
    payload: dict[str, Any] = {}
    for f in _typed(ev.BY_KIND[kind]):
        required = f.default is MISSING and f.default_factory is MISSING
        if not required and draw(st.booleans()):
            continue  # an optional field may be absent (old runs)
        value = _json.filter(lambda v: v is not None) if f.default is None else _json
        if f.name == "verdict":
            value = st.sampled_from(["PASS", "FAIL"])
        elif f.name == "valid":  # an evaluated shot's validity is its kind's
            value = st.just(kind == ev.SHOT_MEASURED)
        payload[f.name] = draw(value)
    names = [f.name for f in _typed(ev.BY_KIND[kind])]
    extra = draw(
        st.dictionaries(st.text(min_size=1, max_size=8).filter(lambda k: k not in names), _json, max_size=4)
    )
    return {**payload, **extra}


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Any:
    with Store.open(tmp_path_factory.mktemp("events") / "e.db") as s:
        s.register_bat("B1", {"id": "B1"})
        yield s


def _canon(value: Any) -> str:
    return json.dumps(value, sort_keys=True)


@pytest.mark.parametrize("kind", sorted(ev.BY_KIND))
def test_every_kind_round_trips_through_the_log(kind: str, store: Store) -> None:
    run_id = store.create_run("bbcor", "B1", {})
    cls = ev.BY_KIND[kind]

    @given(payloads(kind))
    def check(payload: dict[str, Any]) -> None:
        typed = ev.from_payload(kind, payload)
        assert type(typed) is cls and typed.kind == kind
        assert _canon(ev.to_payload(typed)) == _canon(payload)  # the same JSON, byte for byte
        assert typed.data == payload and ev.from_payload(kind, ev.to_payload(typed)) == typed
        entry = store.append(run_id, typed.kind, typed.data)
        (back,) = ev.parse_log([store.entries(run_id)[-1]])
        assert store.entries(run_id)[-1].seq == entry.seq and back == typed

    check()


def test_a_payload_lacking_a_typed_field_is_refused_by_name() -> None:
    with pytest.raises(ev.EventFormatError, match="ShotRequested payload lacks purpose"):
        ev.from_payload("ShotRequested", {"index": 1, "location_in": 6.0})
    older = ev.ShotEvaluated(index=1, outcome=ev.ShotOutcome(valid=True))  # older runs' form: its kind says
    assert ev.from_payload("ShotMeasured", {"index": 1}) == older
    with pytest.raises(ev.EventFormatError, match="no event kind 'Bogus'"):
        ev.from_payload("Bogus", {})
    with pytest.raises(ev.EventFormatError, match="MAYBE"):
        ev.from_payload("RunFinished", {"verdict": "MAYBE", "metric": "bbcor", "limit": 0.5})


def test_the_verdict_is_the_same_string_on_the_wire() -> None:
    assert json.dumps({"verdict": ev.Verdict.PASS}) == '{"verdict": "PASS"}'
    assert ev.Verdict("FAIL") is ev.Verdict.FAIL and ev.Verdict.PASS == "PASS"


def test_the_log_v1_fixture_parses_into_typed_events(tmp_path: Path) -> None:
    copy = tmp_path / "log-v1.db"
    copy.write_bytes(FIXTURE.read_bytes())
    with Store.open(copy) as store:
        for run in store.runs():
            entries = store.entries(run.run_id)
            events = ev.parse_log(entries)
            run_entries = [e for e in entries if e.kind in ev.BY_KIND]
            # every entry that is not a store-level record (RunCreated, RunStatusChanged) is an event
            assert {e.kind for e in entries} - {e.kind for e in run_entries} <= {
                "RunCreated",
                "RunStatusChanged",
            }
            assert len(events) == len(run_entries) > 0
            for entry, typed in zip(run_entries, events, strict=True):
                assert type(typed) is ev.BY_KIND[entry.kind] and typed.persisted
                assert _canon(typed.data) == _canon(entry.payload)
            finished = [e for e in events if isinstance(e, ev.RunFinished)]
            assert all(f.result.verdict is ev.Verdict.PASS for f in finished)


def test_a_damaged_entry_is_one_line_naming_it_not_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rig.cli import main

    path = tmp_path / "r.db"
    with Store.open(path) as store:
        store.register_bat("B1", {"id": "B1"})
        run = store.create_run("bbcor", "B1", {})
        bad = store.append(run, "ShotRequested", {"index": 1, "location_in": 6.0})  # no purpose
    assert main(["report", run, "--format", "json", "--db", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == f"rig: log entry {bad.seq}: ShotRequested payload lacks purpose\n"


def test_a_run_of_this_code_types_every_key_it_writes(tmp_path: Path) -> None:
    """No producer writes an untyped key: a run's events have empty `extra`, their records empty `rest`
    (the untyped parts hold only what older code wrote)."""
    import rig

    seen: list[ev.RunEvent] = []
    bat = rig.Bat.load(Path(__file__).resolve().parents[2] / "protocols" / "examples" / "sample-bat.toml")
    with rig.open_store(tmp_path / "r.db") as store:
        result = rig.certify(
            bat=bat, procedure="bbcor", rig=rig.simulated("lab"), store=store, on_event=seen.append
        )
        logged = ev.parse_log(store.entries(result.run_id))
    assert result.status == "finished"
    kinds = {e.kind for e in seen if e.persisted}
    assert {ev.SHOT_FIRED, ev.SHOT_MEASURED, ev.MOI_MEASURED, ev.RUN_FINISHED} <= kinds
    for e in (*seen, *logged):
        assert dict(e.extra) == {}, (e.kind, sorted(e.extra))
        record = getattr(e, e.RECORD) if e.RECORD else None
        assert record is None or dict(record.rest) == {}, (e.kind, sorted(record.rest))
