"""rig sync: a rig's records pushed to the lab's store, verbatim, idempotent, conflicts refused."""

from __future__ import annotations

import hashlib
import json
import sqlite3
from pathlib import Path

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.store import RecordRefused, Store, StoreError
from rig.store._sync import sync

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
QUICK = ROOT / "tests" / "tui" / "quick-bbcor.toml"


def _certify(path: Path, scene: str = "ideal", run_id: str | None = None) -> str:
    with Store.open(path) as store:
        return certify(store, Procedure.load(QUICK), BAT, sim_config(scene, bat=BAT), run_id=run_id).run_id


def _chain_view(store: Store, run_id: str) -> list[tuple[object, ...]]:
    return [(e.chain_seq, e.kind, e.payload, e.t_utc, e.prev_hash, e.hash) for e in store.entries(run_id)]


def _audit(path: Path) -> int:
    """The auditor's recipe of docs/records.md, written here: every chain links and hashes."""
    heads: dict[str, str] = {}
    db = sqlite3.connect(path)
    try:
        rows = db.execute(
            "SELECT chain, chain_seq, run_id, kind, payload, t_utc, prev_hash, hash FROM log ORDER BY seq"
        ).fetchall()
    finally:
        db.close()
    for chain, n, run_id, kind, payload, t, p, h in rows:
        prev = heads.get(chain, "0" * 64)
        material = json.dumps([prev, n, run_id, kind, t, payload], separators=(",", ":"))
        assert p == prev and h == hashlib.sha256(material.encode()).hexdigest(), (chain, n)
        heads[chain] = h
    return len(rows)


def test_two_rigs_push_their_runs_verbatim_and_a_second_sync_adds_nothing(tmp_path: Path) -> None:
    rig_a, rig_b, lab = tmp_path / "a.db", tmp_path / "b.db", tmp_path / "lab.db"
    run_a, run_b = _certify(rig_a), _certify(rig_b, "lab")
    for source in (rig_a, rig_b):
        with Store.open(source) as s, Store.open(lab) as t:
            report = sync(s, t)
        assert report.runs_copied == 1 and report.runs_up_to_date == 0
    with Store.open(lab) as t, Store.open(rig_a) as a, Store.open(rig_b) as b:
        assert t.verify().ok
        assert {r.run_id for r in t.runs()} == {run_a, run_b}
        assert _chain_view(t, run_a) == _chain_view(a, run_a)  # same hashes, times, payloads
        assert _chain_view(t, run_b) == _chain_view(b, run_b)
        assert t.view_rows("shots", run_b) == b.view_rows("shots", run_b)
        assert t.run(run_a).status == a.run(run_a).status == "finished"
        n = len(t.entries())
        again = sync(a, t)
        assert (again.entries_copied, again.runs_up_to_date) == (0, 1)
        assert len(t.entries()) == n  # idempotent: nothing added, not even a note
        synced = [e.payload for e in t.entries() if e.kind == "RunSynced"]
        assert [(p["run_id"], p["source"]) for p in synced] == [(run_a, str(rig_a)), (run_b, str(rig_b))]
    assert _audit(lab) == n


def test_a_run_that_went_on_offline_gets_only_its_new_entries(tmp_path: Path) -> None:
    rig, lab = tmp_path / "rig.db", tmp_path / "lab.db"
    run = _certify(rig, "faulty")  # the faulty scene interrupts the run part way
    with Store.open(rig) as s, Store.open(lab) as t:
        assert s.run(run).status == "running"
        first = sync(s, t).entries_copied
        held = len(t.entries(run))
    for _ in range(5):
        _certify(rig, "lab", run_id=run)
        with Store.open(rig) as s:
            if s.run(run).status == "finished":
                break
    with Store.open(rig) as s, Store.open(lab) as t:
        report = sync(s, t)
        assert report.entries_copied == len(s.entries(run)) - held > 0 and first == held
        assert _chain_view(t, run) == _chain_view(s, run) and t.verify().ok
        assert t.run(run).status == "finished" and t.run(run).verdict == s.run(run).verdict


def test_a_run_that_went_on_in_both_places_is_refused_and_nothing_is_written(tmp_path: Path) -> None:
    rig, lab = tmp_path / "rig.db", tmp_path / "lab.db"
    run = _certify(rig, "faulty")
    with Store.open(rig) as s, Store.open(lab) as t:
        sync(s, t)
    with Store.open(rig) as s:
        s.append(run, "Note", {"text": "went on at the rig"})
    with Store.open(lab) as t:
        t.append(run, "Note", {"text": "went on in the lab"})
        before = len(t.entries())
    with Store.open(rig) as s, Store.open(lab) as t:
        with pytest.raises(RecordRefused, match=f"run {run}: entry .* differs .* conflicting history"):
            sync(s, t)
        assert len(t.entries()) == before and t.verify().ok


def test_a_source_that_does_not_verify_is_not_copied(tmp_path: Path) -> None:
    rig, lab = tmp_path / "rig.db", tmp_path / "lab.db"
    run = _certify(rig)
    db = sqlite3.connect(rig)
    db.execute("DROP TRIGGER log_no_update")
    db.execute("UPDATE log SET payload = '{}' WHERE run_id = ? AND kind = 'ShotFired'", (run,))
    db.commit()
    db.close()
    with (
        Store.open(rig) as s,
        Store.open(lab) as t,
        pytest.raises(StoreError, match="does not verify, nothing copied"),
    ):
        sync(s, t)
    with Store.open(lab) as t:
        assert t.entries() == []


def test_a_format_1_file_is_refused_with_the_reason(tmp_path: Path) -> None:
    old = tmp_path / "old.db"
    Store.open(old, chain_format=1).close()
    _certify(old)
    with (
        Store.open(old) as s,
        Store.open(tmp_path / "lab.db") as t,
        pytest.raises(StoreError, match="chain format 1"),
    ):
        sync(s, t)


def test_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig, lab = tmp_path / "rig.db", tmp_path / "lab.db"
    _certify(rig)
    assert main(["sync", "--from", str(rig), "--to", str(lab), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["runs_copied"] == 1 and report["entries_copied"] > 10
    assert main(["sync", "--from", str(rig), "--to", str(lab)]) == 0
    assert (
        "0 entries of 0 runs copied, 1 runs already up to date, 0 bats registered, 0 signatures copied"
        in capsys.readouterr().out
    )
    assert main(["sync", "--from", str(tmp_path / "none.db"), "--to", str(lab)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "none.db: no such store" in err


def test_a_signed_run_stays_signed_in_the_lab_store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rig signs its run's own chain position; the copy carries the key and the signature."""
    monkeypatch.setenv("RIG_KEY_DIR", str(tmp_path / "keys"))
    rig, lab = tmp_path / "rig.db", tmp_path / "lab.db"
    assert main(["keys", "create", "--rig", "sim-ideal"]) == 0
    assert main(["keys", "register", "--db", str(rig), "--rig", "sim-ideal"]) == 0
    run = _certify(rig)
    with Store.open(rig) as s, Store.open(lab) as t:
        assert s.verify().runs_signed == 1
        report = sync(s, t)
        assert report.signatures_copied == 1
        checked = t.verify()
        assert checked.ok and (checked.runs_signed, checked.runs_unsigned, checked.runs_bad_signature) == (
            1,
            0,
            0,
        )
        assert sync(s, t).signatures_copied == 0  # idempotent
        (signed,) = t.entries(None, kinds=["RunSigned"])
        last = t.entries(run)[-1]
        assert signed.payload["anchor"] == {"chain_seq": last.chain_seq, "hash": last.hash}
        assert last.seq != s.entries(run)[-1].seq  # another position in the lab's log, same anchor


def test_two_rigs_registering_the_same_bat_at_once_both_certify(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Found by bench_lab_store under load: rig B read the bats before rig A's registration landed,
    then its own registration was refused and its run never started. The race, made certain: the
    bat is registered between B's read and B's registration."""
    lab = tmp_path / "lab.db"
    with Store.open(lab) as store:
        real_bats = Store.bats
        calls = {"n": 0}

        def stale_then_real(self: Store) -> dict[str, object]:
            calls["n"] += 1
            if calls["n"] == 1:  # B's first read: before A registered the bat...
                self.register_bat(BAT.id, BAT.registered())  # ...which A does now
                return {}
            return real_bats(self)

        monkeypatch.setattr(Store, "bats", stale_then_real)
        out = certify(store, Procedure.load(QUICK), BAT, sim_config("ideal", bat=BAT))
        monkeypatch.undo()
        assert out.status == "finished" and store.verify().ok
        assert [e.kind for e in store.entries(None, kinds=["BatRegistered"])] == ["BatRegistered"]
