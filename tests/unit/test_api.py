"""The public Python API (rig.api, exported lazily by `rig`): docs/api.md.

Each result is checked against the store's own record (the log, read back independently of the
facade), the on_event stream against the log's order, resume against the FIRE commands on the wire.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

import rig
from rig.protocols.runner import RunControl
from rig.report.record import run_record
from rig.store import RESERVED_KINDS, Store
from tests.protocols.wire import check_fires

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
_BAT = SAMPLE_BAT.read_text()


def kind_and_data(event: Any) -> tuple[str, dict[str, Any]]:
    """What a test compares of a delivered event (the facade passes events on unchanged)."""
    return event.kind, dict(event.data)


def logged(store: Store, run_id: str) -> list[tuple[str, dict[str, Any]]]:
    """The run's own entries (the store's bookkeeping kinds left out), in log order."""
    return [(e.kind, e.payload) for e in store.entries(run_id) if e.kind not in RESERVED_KINDS]


def test_import_rig_stays_light_and_exports_the_facade(cpu_load: None) -> None:
    """`import rig` loads no pydantic, numpy, drivers or procedures; the names load on first use."""
    code = (
        "import sys, rig\n"
        "heavy = sorted({m.split('.')[0] for m in sys.modules} & "
        "{'pydantic', 'numpy', 'scipy', 'serial', 'drivers', 'protocols', 'simulators'})\n"
        "print(heavy, 'rig.api' in sys.modules)\n"
        "rig.certify\n"
        "print('rig.api' in sys.modules, 'pydantic' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.split("\n")[:2] == ["[] False", "True True"], out.stdout
    assert set(rig.__all__) <= set(dir(rig))
    for name in rig.__all__:
        assert getattr(rig, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'certfy'"):
        rig.certfy  # noqa: B018


def test_result_equals_the_stores_record_and_on_event_sees_every_persisted_event(tmp_path: Path) -> None:
    seen: list[Any] = []
    with rig.open_store(tmp_path / "records.db") as store:
        result = rig.certify(
            bat=rig.Bat.load(SAMPLE_BAT),
            procedure="bbcor",
            rig=rig.simulated("ideal"),
            store=store,
            on_event=seen.append,
        )
        record = run_record(store, result.run_id)
        summary = store.run(result.run_id)
        log = logged(store, result.run_id)
    verdict = record["verdict"]
    assert result.status == "finished" == summary.status and result.finished
    assert isinstance(result.verdict, rig.Verdict) and result.verdict == summary.verdict == verdict["verdict"]
    assert result.mean == verdict["mean"] == pytest.approx(sum(verdict["hits"]) / verdict["n_hits"])
    assert result.expanded_uncertainty == verdict["U"] == pytest.approx(verdict["coverage_k"] * verdict["u"])
    assert (result.k, result.limit, result.location_in) == (
        verdict["coverage_k"],
        verdict["limit"],
        verdict["location_in"],
    )
    assert dict(result.cross_check or {}) == record["cross_check"]
    assert result.shots == len(record["shots"]) > 0
    assert result.limit == 0.5 and result.k == 2.0  # the BBCOR procedure's limit and coverage factor
    # the guarded decision rule, from the numbers alone
    assert (result.verdict == "PASS") == (result.mean + result.expanded_uncertainty <= result.limit)
    with pytest.raises(AttributeError):
        result.mean = 0.0  # type: ignore[misc]  # frozen

    # every persisted event reached on_event, in the order of the log (and nothing in between
    # was persisted that on_event did not see); live-only events come in between
    kinds = {k for k, _ in log}
    persisted = [(k, json.loads(json.dumps(d))) for k, d in map(kind_and_data, seen) if k in kinds]
    assert persisted == log  # as JSON: the store keeps tuples as lists
    assert len(seen) > len(log)  # the live events (gate crossings, ...) too


def test_a_url_opens_the_same_store(tmp_path: Path) -> None:
    path = tmp_path / "url.db"
    with rig.open_store(f"sqlite:///{path}") as store:
        assert store.path == path and store.runs() == []
    assert path.exists()
    with pytest.raises(rig.RigError, match="mysql:// stores are not supported"):
        rig.open_store("mysql://lab/records")
    # a PostgreSQL URL is a lab database: an unreachable one is one line naming it, password masked
    with pytest.raises(rig.RigError, match=r"postgresql://ann:\*\*\*@127\.0\.0\.1:1/records: cannot connect"):
        rig.open_store("postgresql://ann:secret@127.0.0.1:1/records")


@pytest.mark.parametrize(
    ("call", "names"),
    [
        (lambda p: rig.Bat.load(p / "missing.toml"), ["missing.toml", "no such file"]),
        (lambda p: rig.Bat.load(_write(p / "bat.toml", '[bat]\nid = "X"\n')), ["bat.toml", "length_in"]),
        (lambda p: rig.Bat.load(_write(p / "bat.toml", _BAT.replace("33.0", "99.0"))), ["length_in", "42"]),
        (lambda p: rig.simulated("moon"), ["moon", "built-in scenes"]),
        (lambda p: rig.simulated("ideal", cannon_cycle_s=-1.0), ["cannon_cycle_s"]),
        (lambda p: rig.simulated("ideal", turbo=True), ["turbo"]),
        (lambda p: rig.from_config(p / "rig.toml"), ["rig.toml", "no such file"]),
        (lambda p: rig.open_store(_write(p / "notes.db", "not a database")), ["notes.db"]),
    ],
)
def test_bad_input_raises_a_rig_error_naming_the_cause(tmp_path: Path, call: Any, names: list[str]) -> None:
    with pytest.raises(rig.RigError) as caught:
        call(tmp_path)
    for name in names:
        assert name in str(caught.value)
    assert "\n" not in str(caught.value)


def test_certify_refuses_bad_input_before_recording_anything(tmp_path: Path) -> None:
    bat = rig.Bat.load(SAMPLE_BAT)
    with rig.open_store(tmp_path / "r.db") as store:
        with pytest.raises(rig.RigError, match="nope: no such procedure; built-in ones are bbcor"):
            rig.certify(bat=bat, procedure="nope", rig=rig.simulated("ideal"), store=store)
        with pytest.raises(rig.RigError, match=r"rig must be rig\.simulated"):
            rig.certify(bat=bat, procedure="bbcor", rig="lab", store=store)  # type: ignore[arg-type]
        with pytest.raises(rig.RigError, match="give bat= and procedure="):
            rig.certify(procedure="bbcor", rig=rig.simulated("ideal"), store=store)
        with pytest.raises(rig.RigError, match="no run"):
            rig.certify(rig=rig.simulated("ideal"), store=store, resume="0123abcd")
        assert store.runs() == [] and store.entries(None) == []


def test_an_aborted_run_resumes_through_the_facade_firing_no_shot_twice(tmp_path: Path) -> None:
    """Abort after shot 3 is fired (RunControl, from on_event); resume by the run id to a verdict."""
    control = RunControl()

    def abort_after_third(event: Any) -> None:
        kind, data = kind_and_data(event)
        if kind == "ShotFired" and data["index"] == 3:
            control.abort("stopped by the script")

    bat = rig.Bat.load(SAMPLE_BAT)
    with rig.open_store(tmp_path / "r.db") as store:
        first = rig.certify(
            bat=bat,
            procedure="bbcor",
            rig=rig.simulated("ideal"),
            store=store,
            on_event=abort_after_third,
            control=control,
        )
        assert first.status == "interrupted" and first.verdict is None and first.mean is None
        assert first.reason == "stopped by the script" and first.shots == 3
        kept = logged(store, first.run_id)
        assert kept[-1] == ("RunInterrupted", {"reason": "stopped by the script", "budget_exceeded": False})
        assert store.run(first.run_id).status == "running"  # open, resumable

        with pytest.raises(rig.RigError, match="started with another bat"):
            rig.certify(
                bat=bat.model_copy(update={"id": "OTHER"}),
                rig=rig.simulated("ideal"),
                store=store,
                resume=first,
            )
        seen: list[Any] = []
        done = rig.certify(rig=rig.simulated("ideal"), store=store, resume=first, on_event=seen.append)
        entries = store.entries(first.run_id)
        after = logged(store, first.run_id)
        record = run_record(store, first.run_id)

    assert done.run_id == first.run_id and done.status == "finished"
    assert done.verdict == record["verdict"]["verdict"] and done.mean == record["verdict"]["mean"]
    assert after[: len(kept)] == kept  # nothing recorded before the interruption was lost or changed
    requested = Counter(e.payload["index"] for e in entries if e.kind == "ShotRequested")
    assert all(n == 1 for n in requested.values()) and done.shots == len(requested)
    per_shot = check_fires(entries)  # each FIRE on the wire at its shot's recorded stage position
    assert all(n == 1 for n in per_shot.values()) and set(per_shot) == set(requested)
    resumed_events = [kind_and_data(e) for e in seen]
    assert [kind for kind, _ in resumed_events[:2]] == ["RigNamed", "RunResumed"]  # the rig, then the run


def test_a_device_fault_returns_an_interrupted_result_and_keeps_the_record(tmp_path: Path) -> None:
    """The faulty scene unplugs the gates at its seventh shot: no raise, the record kept, resumable."""
    with rig.open_store(tmp_path / "r.db") as store:
        result = rig.certify(
            bat=rig.Bat.load(SAMPLE_BAT), procedure="bbcor", rig=rig.simulated("faulty"), store=store
        )
        entries = store.entries(result.run_id)
    assert result.status == "interrupted" and not result.finished and result.verdict is None
    assert "gates" in result.reason
    last = entries[-1]
    assert last.kind == "RunInterrupted" and last.payload["reason"] == result.reason
    requested = [e.payload["index"] for e in entries if e.kind == "ShotRequested"]
    assert requested == list(range(1, len(requested) + 1)) and len(requested) >= 7  # up to the fault
    outcomes = [e.payload["index"] for e in entries if e.kind in ("ShotMeasured", "ShotRejected", "ShotLost")]
    assert outcomes == requested[: len(outcomes)] and len(outcomes) >= len(requested) - 1
    assert result.shots == len(requested)


def test_from_config_runs_the_rig_file(tmp_path: Path) -> None:
    """A rig file's ports may name simulated devices: the same facade, a lab's own file."""
    text = (
        "[ports]\n"
        'cannon = "sim://cannon?scene=ideal&rig=api-test"\n'
        'gates = "sim://gates?scene=ideal&rig=api-test"\n'
        'clamp = "sim://clamp?scene=ideal&rig=api-test"\n'
    )
    spec = rig.from_config(_write(tmp_path / "rig.toml", text))
    assert spec.config is not None and spec.config.ports.cannon.startswith("sim://cannon")
    assert spec.config_for(rig.Bat.load(SAMPLE_BAT)) is spec.config


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_an_error_in_on_event_interrupts_the_run_and_keeps_the_event(tmp_path: Path) -> None:
    """A script's own bug in on_event: the run is interrupted (not torn), the event already recorded."""

    def broken(event: Any) -> None:
        if kind_and_data(event)[0] == "ShotFired":
            raise ValueError("the script's own bug")

    with rig.open_store(tmp_path / "r.db") as store:
        result = rig.certify(
            bat=rig.Bat.load(SAMPLE_BAT),
            procedure="bbcor",
            rig=rig.simulated("ideal"),
            store=store,
            on_event=broken,
        )
        kinds = [k for k, _ in logged(store, result.run_id)]
    assert result.status == "interrupted" and result.reason == "unexpected ValueError: the script's own bug"
    assert kinds[-1] == "RunInterrupted" and kinds.count("ShotFired") == 1  # recorded, then stopped
    assert "ShotMeasured" not in kinds and "ShotRejected" not in kinds  # nothing shot after it
