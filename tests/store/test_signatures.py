"""Signed run anchors: verify() checks each RunSigned; a forger who recomputes the chain is caught
only where the rig signed (with no key, the same forgery goes unseen: the chain alone cannot tell).

These forgeries rewrite the single chain of format 1; test_chains.py covers what format 2 finds
without keys."""

from __future__ import annotations

import base64
import contextlib
import hashlib
import io
import json
import sqlite3
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from rig.cli import main
from rig.keys import Signer, create_key, load_signer, register, sign_run
from rig.store import GENESIS_HASH, Store, canonical_json, entry_hash
from tests.store.conftest import raw

RIG = {"name": "r1", "serial": "SN-7", "software": "0.1.0"}
Edit = Callable[[int, str | None, str, dict[str, Any], dict[int, tuple[int, str]]], dict[str, Any] | None]


def _signer(tmp_path: Path, rig: str = "r1", folder: str = "keys") -> Signer:
    create_key(rig, tmp_path / folder)
    signer = load_signer(rig, tmp_path / folder)
    assert signer is not None
    return signer


def _run(store: Store, signer: Signer | None, *, rig: dict[str, Any] = RIG, shots: int = 3) -> str:
    """A sealed run of rig `rig` (signed by `signer` if given); the bat is registered on first use."""
    if "B-1" not in store.bats():
        store.register_bat("B-1", {"model": "X33"})
    run = store.create_run("bbcor", "B-1", {"procedure": "NCAA BBCOR", "rig": rig})
    for i in range(shots):
        store.append(run, "ShotMeasured", {"shot": i, "bbcor": 0.47 + i / 100})
    store.set_run_status(run, "finished", "PASS")
    if signer is not None:
        sign_run(store, run, signer)
    return run


def forge(path: Path, edit: Edit) -> None:
    """Rewrite the log as a forger who read the code: edit or drop rows, renumber, recompute every
    hash with the store's own entry_hash, restore the triggers, rebuild the tables.

    `edit(old_seq, run_id, kind, payload, rewritten)` returns the new payload (None: drop the row);
    `rewritten` maps each earlier row's old seq to its new (seq, hash).
    """
    with raw(path) as db:
        rows = db.execute("SELECT seq, run_id, kind, payload, t_utc FROM log ORDER BY seq").fetchall()
        db.execute("BEGIN")
        db.execute("DELETE FROM log")
        prev, seq, rewritten = GENESIS_HASH, 0, {}
        for old_seq, run_id, kind, payload, t_utc in rows:
            new = edit(old_seq, run_id, kind, json.loads(payload), rewritten)
            if new is None:
                continue
            seq += 1
            text = canonical_json(new)
            digest = entry_hash(prev, seq, run_id, kind, t_utc, text)
            db.execute(
                "INSERT INTO log (seq, run_id, kind, payload, t_utc, prev_hash, hash) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (seq, run_id, kind, text, t_utc, prev, digest),
            )
            rewritten[old_seq] = (seq, digest)
            prev = digest
        db.execute("COMMIT")
    with Store.open(path, chain_format=1) as store:
        store.rebuild_indexes()


def _better_shot(run: str) -> Edit:
    """Shot 1 of `run` made a better bat (the forgery), every other row kept."""

    def edit(seq: int, run_id: str | None, kind: str, payload: dict[str, Any], _: Any) -> dict[str, Any]:
        if run_id == run and kind == "ShotMeasured" and payload["shot"] == 1:
            return {**payload, "bbcor": 0.43}
        return payload

    return edit


def _chain_intact(store: Store) -> None:
    report = store.verify()
    assert report.first_broken_seq is None, report
    assert not [p for p in report.problems if "RunSigned" not in p and "not signed" not in p], report


def _last_entry(path: Path, run: str) -> tuple[int, str]:
    with sqlite3.connect(path) as db:
        sql = "SELECT seq, hash FROM log WHERE run_id = ? ORDER BY seq DESC LIMIT 1"
        return db.execute(sql, (run,)).fetchone()


def test_a_signed_run_verifies_and_its_signature_is_ed25519_over_the_last_entry(tmp_path: Path) -> None:
    signer = _signer(tmp_path)
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        register(store, signer)
        run = _run(store, signer)
        report = store.verify()
        signed = store.entries(None, kinds=["RunSigned"])
    assert report.ok, report
    assert (report.runs_signed, report.runs_unsigned, report.runs_bad_signature) == (1, 0, 0)
    # checked apart from the code: the private key file, the log read with sqlite3, JSON by hand
    key = serialization.load_pem_private_key((tmp_path / "keys" / "r1.key").read_bytes(), None)
    assert isinstance(key, Ed25519PrivateKey)
    public_raw = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    seq, digest = _last_entry(path, run)
    (entry,) = signed
    assert entry.payload["anchor"] == {"seq": seq, "hash": digest}
    assert entry.payload["fingerprint"] == hashlib.sha256(public_raw).hexdigest()[:16]
    assert entry.payload["rig"] == "r1" and entry.payload["run_id"] == run
    message = json.dumps({"run_id": run, "seq": seq, "hash": digest}, sort_keys=True, separators=(",", ":"))
    key.public_key().verify(base64.b64decode(entry.payload["signature"]), message.encode())


def test_a_recomputed_chain_verifies_but_the_signature_does_not(tmp_path: Path) -> None:
    signer = _signer(tmp_path)
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        register(store, signer)
        run = _run(store, signer)
    forge(path, _better_shot(run))
    with Store.open(path, chain_format=1) as store:
        assert [e.payload["bbcor"] for e in store.entries(run, kinds=["ShotMeasured"])][1] == 0.43  # forged
        _chain_intact(store)
        report = store.verify()
    assert not report.ok
    assert (report.runs_signed, report.runs_bad_signature) == (0, 1)
    assert any(f"RunSigned for run {run}" in p and "changed after" in p for p in report.problems)


def test_a_forger_who_also_rewrites_the_anchor_cannot_sign_it(tmp_path: Path) -> None:
    signer = _signer(tmp_path)
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        register(store, signer)
        run = _run(store, signer)
        last_seq = store.run(run).last_seq
    better = _better_shot(run)

    def edit(seq: int, run_id: str | None, kind: str, payload: dict[str, Any], done: Any) -> dict[str, Any]:
        if kind == "RunSigned":
            new_seq, new_hash = done[last_seq]
            return {**payload, "anchor": {"seq": new_seq, "hash": new_hash}}
        return better(seq, run_id, kind, payload, done)

    forge(path, edit)
    with Store.open(path, chain_format=1) as store:
        _chain_intact(store)
        report = store.verify()
        (signed,) = store.entries(None, kinds=["RunSigned"])
    assert (signed.payload["anchor"]["seq"], signed.payload["anchor"]["hash"]) == _last_entry(path, run)
    assert not report.ok and report.runs_bad_signature == 1
    assert any("does not verify" in p for p in report.problems), report.problems


def test_a_forger_who_signs_with_a_key_of_their_own_is_caught(tmp_path: Path) -> None:
    signer, forger = _signer(tmp_path), _signer(tmp_path, folder="forger")
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        register(store, signer)
        run = _run(store, None)
        sign_run(store, run, forger)  # a well-formed signature, by a key the lab never listed
        report = store.verify()
    assert not report.ok and report.runs_bad_signature == 1
    assert any(forger.fingerprint in p and signer.fingerprint in p for p in report.problems), report.problems


def test_a_removed_signature_is_reported(tmp_path: Path) -> None:
    signer = _signer(tmp_path)
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        register(store, signer)
        run = _run(store, signer)
    better = _better_shot(run)
    forge(path, lambda s, r, k, p, d: None if k == "RunSigned" else better(s, r, k, p, d))
    with Store.open(path, chain_format=1) as store:
        _chain_intact(store)
        assert store.entries(None, kinds=["RunSigned"]) == []
        report = store.verify()
    assert not report.ok and (report.runs_signed, report.runs_unsigned) == (0, 1)
    assert any(f"run {run} of rig r1 is sealed" in p and "not signed" in p for p in report.problems)


def test_without_keys_the_same_forgery_goes_undetected(tmp_path: Path) -> None:
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        run = _run(store, None)
        before = store.verify()
    forge(path, _better_shot(run))
    with Store.open(path, chain_format=1) as store:
        report = store.verify()
        shots = [e.payload["bbcor"] for e in store.entries(run, kinds=["ShotMeasured"])]
    assert before.ok and shots[1] == 0.43
    assert report.ok, report  # the limit docs/records.md states: only a key (or an outside anchor) tells
    assert (report.runs_signed, report.runs_unsigned, report.runs_bad_signature) == (0, 1, 0)


def test_a_replaced_key_keeps_old_signatures_checkable_and_stops_new_ones(tmp_path: Path) -> None:
    old, new = _signer(tmp_path), _signer(tmp_path, folder="new")
    with Store.open(tmp_path / "rig.db", chain_format=1) as store:
        register(store, old)
        first = _run(store, old)
        register(store, new, replace=True)
        _run(store, new)
        stale = _run(store, old)  # signed after the replacement with the retired key
        report = store.verify()
    assert (report.runs_signed, report.runs_bad_signature) == (2, 1), report
    assert [p for p in report.problems if first in p] == []
    assert any(stale in p and f"key then was {new.fingerprint}" in p for p in report.problems)


def test_runs_signed_before_the_key_was_listed_check_against_it(tmp_path: Path) -> None:
    signer = _signer(tmp_path)
    with Store.open(tmp_path / "rig.db", chain_format=1) as store:
        _run(store, None)  # before the rig had a key: not required to be signed
        _run(store, signer)  # signed, the key listed only afterwards
        register(store, signer)
        report = store.verify()
    assert report.ok, report
    assert (report.runs_signed, report.runs_unsigned, report.runs_bad_signature) == (1, 1, 0)


def test_an_unlisted_rig_signature_counts_as_unsigned_and_old_runs_are_not_required(tmp_path: Path) -> None:
    signer = _signer(tmp_path)
    with Store.open(tmp_path / "rig.db", chain_format=1) as store:
        _run(store, signer)  # no key registered at all: nothing to check it against
        old = store.create_run("bbcor", "B-1", {"procedure": "NCAA BBCOR"})  # from before identities
        store.set_run_status(old, "aborted")
        register(store, signer)
        report = store.verify()
    assert report.ok, report
    assert (report.runs_signed, report.runs_unsigned) == (1, 1)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda p: {**p, "fingerprint": "0" * 16}, "is not the key's"),
        (lambda p: {**p, "public_key": base64.b64encode(b"x" * 31).decode()}, "31 bytes"),
        (lambda p: {**p, "public_key": "not base64!"}, "not base64"),
    ],
)
def test_a_malformed_key_registration_is_reported(tmp_path: Path, change: Callable, needle: str) -> None:
    signer = _signer(tmp_path)
    payload = {"rig": "r1", "public_key": signer.public_b64, "fingerprint": signer.fingerprint}
    with Store.open(tmp_path / "rig.db", chain_format=1) as store:
        store.append(None, "RigKeyRegistered", change(payload))
        report = store.verify()
    assert not report.ok
    assert any("RigKeyRegistered refused" in p and needle in p for p in report.problems), report.problems


def test_a_forger_who_replaces_the_registered_key_passes_the_file_alone_but_not_a_trusted_key(
    tmp_path: Path,
) -> None:
    signer, forger = _signer(tmp_path), _signer(tmp_path, folder="forger")
    path = tmp_path / "rig.db"
    with Store.open(path, chain_format=1) as store:
        register(store, signer)
        run = _run(store, signer)
        last_seq = store.run(run).last_seq
    better = _better_shot(run)

    def edit(seq: int, run_id: str | None, kind: str, payload: dict[str, Any], done: Any) -> dict[str, Any]:
        if kind == "RigKeyRegistered":
            return {**payload, "public_key": forger.public_b64, "fingerprint": forger.fingerprint}
        if kind == "RunSigned":
            new_seq, new_hash = done[last_seq]
            anchor = {"run_id": run, "seq": new_seq, "hash": new_hash}
            message = json.dumps(anchor, sort_keys=True, separators=(",", ":")).encode()
            signature = base64.b64encode(forger.key.sign(message)).decode()
            anchor = {"seq": new_seq, "hash": new_hash}
            return {**payload, "fingerprint": forger.fingerprint, "anchor": anchor, "signature": signature}
        return better(seq, run_id, kind, payload, done)

    forge(path, edit)
    with Store.open(path, chain_format=1) as store:
        report = store.verify()
    assert report.ok and report.runs_signed == 1, report  # the limit docs/records.md states
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["verify", "--db", str(path), "--trusted-key", f"r1:{signer.fingerprint}"])
    assert code == 1, err.getvalue()
    assert f"rig r1's registered key {forger.fingerprint} is not a trusted one" in out.getvalue()
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["verify", "--db", str(path), "--trusted-key", f"r1:{forger.fingerprint}"]) == 0


@pytest.mark.parametrize("pin", ["r1", "r1:XYZ", "../r1:0123456789abcdef", "r1:0123456789ABCDEF"])
def test_a_malformed_trusted_key_is_one_line(tmp_path: Path, pin: str) -> None:
    with Store.open(tmp_path / "rig.db", chain_format=1):
        pass
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["verify", "--db", str(tmp_path / "rig.db"), "--trusted-key", pin])
    assert code == 2 and len(err.getvalue().strip().splitlines()) == 1 and "RIG:FINGERPRINT" in err.getvalue()


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda p: {**p, "run_id": 5}, "malformed"),
        (lambda p: {k: v for k, v in p.items() if k != "anchor"}, "malformed"),
        (lambda p: {**p, "anchor": {"seq": True, "hash": p["anchor"]["hash"]}}, "malformed anchor"),
        (lambda p: {**p, "run_id": "f" * 32}, "no such run"),
        (lambda p: {**p, "rig": "r2"}, "recorded on rig r1"),
        (lambda p: {**p, "signature": 123}, "not base64"),
        (lambda p: {**p, "signature": base64.b64encode(b"\0" * 64).decode()}, "does not verify"),
    ],
)
def test_a_malformed_signature_entry_is_reported_not_a_crash(
    tmp_path: Path, change: Callable, needle: str
) -> None:
    signer = _signer(tmp_path)
    with Store.open(tmp_path / "rig.db", chain_format=1) as store:
        register(store, signer)
        run = _run(store, None)
        sign_run(store, run, signer)
        (good,) = store.entries(None, kinds=["RunSigned"])
    path = tmp_path / "rig.db"
    forge(path, lambda s, r, k, p, d: change(p) if k == "RunSigned" else p)
    with Store.open(path, chain_format=1) as store:
        report = store.verify()
    assert not report.ok and report.runs_signed == 0
    assert any("RunSigned" in p and needle in p for p in report.problems), (good.payload, report.problems)


def forge2(path: Path, run: str) -> None:
    """Chain format 2: a forger who read the code makes shot 1 of `run` a better bat, re-hashes the
    run's chain, points the lab chain's anchors of it at the new hashes and re-hashes the lab chain."""
    with raw(path) as db:
        rows = db.execute(
            "SELECT seq, run_id, kind, payload, t_utc, chain, chain_seq FROM log ORDER BY chain, chain_seq"
        ).fetchall()
        new_hash: dict[str, str] = {}  # old hash -> new hash, for the run's entries
        heads: dict[str, str] = {}
        db.execute("BEGIN")
        for seq, run_id, kind, payload, t_utc, chain, number in sorted(
            rows, key=lambda r: (r[5] == "lab", r[5], r[6])
        ):
            data = json.loads(payload)
            if run_id == run and kind == "ShotMeasured" and data["shot"] == 1:
                data = {**data, "bbcor": 0.43}
            if chain == "lab" and data.get("run_id") == run and "hash" in data:  # RunOpened, RunSealed
                old = data["hash"]
                data = {**data, "hash": new_hash.get(old, old)}
            text = canonical_json(data)
            prev = heads.get(chain, GENESIS_HASH)
            digest = entry_hash(prev, number, run_id, kind, t_utc, text)
            (old_hash,) = db.execute("SELECT hash FROM log WHERE seq = ?", (seq,)).fetchone()
            new_hash[old_hash] = digest
            db.execute(
                "UPDATE log SET payload = ?, prev_hash = ?, hash = ? WHERE seq = ?", (text, prev, digest, seq)
            )
            heads[chain] = digest
        db.execute("COMMIT")


@pytest.mark.parametrize("signed", [True, False])
def test_format_2_a_rewritten_run_with_rewritten_lab_anchors_is_caught_only_by_its_signature(
    tmp_path: Path, signed: bool
) -> None:
    path = tmp_path / "rig.db"
    signer = _signer(tmp_path) if signed else None
    with Store.open(path) as store:
        assert store.chain_format == 2
        if signer is not None:
            register(store, signer)
        run = _run(store, signer)
        _run(store, signer)  # another run, untouched
        assert store.verify().ok
    forge2(path, run)
    with Store.open(path) as store:
        report = store.verify()
        assert [e.payload["bbcor"] for e in store.entries(run, kinds=["ShotMeasured"])][1] == 0.43
    assert report.first_broken_seq is None  # every chain and every anchor holds
    if signed:
        assert not report.ok and report.runs_bad_signature == 1 and report.runs_signed == 1
        assert any(
            f"RunSigned for run {run}" in p and "not the run's last entry" in p for p in report.problems
        )
    else:
        assert report.ok  # without keys the forgery is not seen: the documented limit
