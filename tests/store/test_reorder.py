"""Reordering a run's entries (issue 21, item 3): swapping the `seq` of two entries of a sealed,
signed run changes what its certificate reads; the chain and the signature must cover the order,
in both chain formats, and verify must name the entry out of place."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from rig.cli import main
from rig.keys import create_key, keys_in, load_signer, recorded_rig, register
from rig.report.record import run_record
from rig.store import Store
from tests.store.conftest import raw
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE, run_cli


def swap_seq(path: Path, a: int, b: int) -> None:
    """Swap the global seq of two rows (the triggers dropped and recreated, as a forger would)."""
    with raw(path) as db:
        db.execute("BEGIN")
        db.execute("UPDATE log SET seq = -1 WHERE seq = ?", (a,))
        db.execute("UPDATE log SET seq = ? WHERE seq = ?", (a, b))
        db.execute("UPDATE log SET seq = ? WHERE seq = -1", (b,))
        db.execute("COMMIT")


def _fill(store: Store) -> str:
    """A bat, a finished run of five shots, another run's entry in between, and a note."""
    store.register_bat("B-1", {"model": "X33"})
    run = store.create_run("bbcor", "B-1", {})
    other = store.create_run("besr", "B-1", {})
    for i in range(5):
        store.append(run, "ShotMeasured", {"shot": i})
        if i == 2:
            store.append(other, "ShotFired", {"shot": 0})
    store.append(None, "Note", {"text": "coffee"})
    store.set_run_status(run, "finished", "PASS")
    return run


@pytest.mark.parametrize("fmt", [1, 2])
def test_two_entries_of_a_run_swapped_are_named_out_of_place(tmp_path: Path, fmt: int) -> None:
    with Store.open(tmp_path / "r.db", chain_format=fmt) as store:
        run = _fill(store)
        shots = [e for e in store.entries(run) if e.kind == "ShotMeasured"]
        first, last = shots[1], shots[4]
        assert store.verify().ok
    swap_seq(tmp_path / "r.db", first.seq, last.seq)
    with Store.open(tmp_path / "r.db") as store:
        assert [e.payload["shot"] for e in store.entries(run, kinds=["ShotMeasured"])] == [0, 4, 2, 3, 1]
        report = store.verify()
        assert not report.ok
        text = "\n".join(report.problems)
        assert "out of place" in (report.reason or ""), report
        if fmt == 2:  # each entry named by its run and its number there
            assert f"run {run} entry {first.chain_seq}" in text and "out of place" in text
            assert f"run {run} entry {last.chain_seq}" in text
            run_report = store.verify_run(run)
            assert not run_report.ok and "out of place" in "\n".join(run_report.problems)
        else:  # the entry's own hash says where it was written
            assert f"seq {first.seq}: out of place: its hash places it at seq {last.seq}" in text
            assert f"seq {last.seq}: out of place: its hash places it at seq {first.seq}" in text


def test_entries_of_different_chains_interleave_freely(tmp_path: Path) -> None:
    """Format 2 orders entries within a chain only: two runs and the lab chain interleave."""
    with Store.open(tmp_path / "r.db") as store:
        _fill(store)
        assert store.verify().ok


def _certified(tmp_path: Path, fmt: int) -> tuple[Path, str, str]:
    """A quick certification on the simulated rig, sealed and signed with the rig's registered key."""
    db = tmp_path / "c.db"
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    Store.open(db, chain_format=fmt).close()
    create_key("sim-ideal")
    signer = load_signer("sim-ideal")
    assert signer is not None
    with Store.open(db) as store:
        register(store, signer)
    argv = ["certify", "--procedure", str(tmp_path / "proc.toml"), "--bat", str(tmp_path / "bat.toml")]
    result = run_cli([*argv, "--sim", "ideal", "--db", str(db)], db)
    assert result.code == 0, result.err
    with Store.open(db) as store:
        run = store.runs()[-1].run_id
        assert recorded_rig(store, run) == "sim-ideal"
        report = store.verify()
        assert report.ok and report.runs_signed == 1, report
        pin = f"sim-ideal:{keys_in(store)[0].fingerprint}"
    return db, run, pin


def _verify(db: Path, *args: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(["verify", "--db", str(db), "--json", *args])
    return code, "\n".join(json.loads(out.getvalue())["problems"])


@pytest.mark.parametrize("fmt", [1, 2])
def test_a_shot_moved_in_a_signed_certification_fails_verify_and_the_trusted_key(
    tmp_path: Path, fmt: int
) -> None:
    """The audit's case: a shot's outcome moved before its request leaves the shot not evaluated."""
    db, run, pin = _certified(tmp_path, fmt)
    with Store.open(db) as store:
        before = run_record(store, run)
        entries = store.entries(run)
    requested = next(e for e in entries if e.kind == "ShotRequested" and e.payload["index"] == 5)
    measured = next(e for e in entries if e.kind == "ShotMeasured" and e.payload["index"] == 5)
    swap_seq(db, requested.seq, measured.seq)
    with Store.open(db) as store:
        after = run_record(store, run)
    shot = (
        {s["index"]: s["status"] for s in before["shots"]},
        {s["index"]: s["status"] for s in after["shots"]},
    )
    assert shot[0][5] == "valid" and shot[1][5] == "requested"  # what a certificate reads changed...
    code, problems = _verify(db, "--trusted-key", pin)
    assert code == 1 and "out of place" in problems, problems  # ...and verify says where
    code, problems = _verify(db, "--run", run)
    assert code == 1 and "out of place" in problems, problems
