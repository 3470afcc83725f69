"""Rig identity and `rig keys`: key files (0600, never overwritten, refused when open to others),
registered public keys, runs that record their rig and are signed when sealed."""

from __future__ import annotations

import base64
import contextlib
import hashlib
import io
import json
import os
import re
import shutil
import socket
import sqlite3
import stat
from pathlib import Path

import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

import rig
from rig.certification import Signoff, end_run
from rig.cli import main
from rig.core.config import RigConfig
from rig.core.errors import ConfigError
from rig.session import sim_config
from rig.store import Store
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
PORTS = {"cannon": "/dev/ttyUSB0", "gates": "/dev/ttyUSB1", "clamp": "/dev/ttyUSB2"}


def cli(*argv: str) -> tuple[int, str, str]:
    """main(argv): exit code, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(argv))
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue(), err.getvalue()


def refused(result: tuple[int, str, str], *needles: str) -> None:
    code, _, err = result
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


def public_raw(key_file: Path) -> bytes:
    """The raw public key of a PEM private key file, read with cryptography directly."""
    key = serialization.load_pem_private_key(key_file.read_bytes(), None)
    assert isinstance(key, Ed25519PrivateKey)
    return key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def test_create_writes_a_private_key_only_its_owner_reads_and_prints_its_fingerprint(tmp_path: Path) -> None:
    code, out, err = cli("keys", "create", "--rig", "lab-1", "--dir", str(tmp_path / "k"))
    assert code == 0, err
    key_file = tmp_path / "k" / "lab-1.key"
    assert stat.S_IMODE(key_file.stat().st_mode) == 0o600
    assert hashlib.sha256(public_raw(key_file)).hexdigest()[:16] in out


def test_create_uses_rig_key_dir_and_never_overwrites_a_key() -> None:
    folder = Path(os.environ["RIG_KEY_DIR"])
    assert cli("keys", "create", "--rig", "lab-1")[0] == 0
    before = (folder / "lab-1.key").read_bytes()
    refused(cli("keys", "create", "--rig", "lab-1"), "has a key already", "kept")
    assert (folder / "lab-1.key").read_bytes() == before


@pytest.mark.parametrize("name", ["../escape", "a/b", ".hidden", "", "x" * 65, "sp ace"])
def test_create_refuses_a_name_that_is_not_a_plain_file_name(tmp_path: Path, name: str) -> None:
    refused(cli("keys", "create", "--rig", name, "--dir", str(tmp_path / "k")), "rig name")
    assert not (tmp_path / "k").exists() and not (tmp_path / "escape.key").exists()


def test_a_key_file_open_to_others_is_refused_and_nothing_is_registered(tmp_path: Path) -> None:
    keys, db = tmp_path / "k", tmp_path / "r.db"
    cli("keys", "create", "--rig", "lab-1", "--dir", str(keys))
    (keys / "lab-1.key").chmod(0o640)
    result = cli("keys", "register", "--db", str(db), "--rig", "lab-1", "--dir", str(keys))
    refused(result, "chmod 600", "640")
    assert not db.exists()


def test_register_lists_the_public_key_once_and_a_new_key_only_with_replace(tmp_path: Path) -> None:
    db, first, second = str(tmp_path / "r.db"), tmp_path / "k1", tmp_path / "k2"
    cli("keys", "create", "--rig", "lab-1", "--dir", str(first))
    cli("keys", "create", "--rig", "lab-1", "--dir", str(second))
    assert cli("keys", "register", "--db", db, "--rig", "lab-1", "--dir", str(first))[0] == 0
    code, out, _ = cli("keys", "register", "--db", db, "--rig", "lab-1", "--dir", str(first))
    assert code == 0 and "already" in out
    refused(cli("keys", "register", "--db", db, "--rig", "lab-1", "--dir", str(second)), "--replace")
    assert cli("keys", "register", "--db", db, "--rig", "lab-1", "--dir", str(second), "--replace")[0] == 0
    code, out, _ = cli("keys", "list", "--db", db, "--json")
    listed = json.loads(out)
    raws = [public_raw(first / "lab-1.key"), public_raw(second / "lab-1.key")]
    assert [(k["rig"], k["current"]) for k in listed] == [("lab-1", False), ("lab-1", True)]
    for row, raw in zip(listed, raws, strict=True):
        assert row["public_key"] == base64.b64encode(raw).decode()
        assert row["fingerprint"] == hashlib.sha256(raw).hexdigest()[:16]
    with Store.open(db) as store:
        assert len(store.entries(None, kinds=["RigKeyRegistered"])) == 2
        assert all(e.run_id is None for e in store.entries(None, kinds=["RigKeyRegistered"]))


def test_register_without_a_key_and_list_of_a_missing_store_say_so(tmp_path: Path) -> None:
    result = cli("keys", "register", "--db", str(tmp_path / "r.db"), "--rig", "nokey")
    refused(result, "no key", "rig keys create")
    refused(cli("keys", "list", "--db", str(tmp_path / "none.db")), "no such store")


def test_identity_defaults_sim_scene_or_host_and_the_table_wins() -> None:
    assert sim_config("lab").identity_name() == "sim-lab"
    ideal = sim_config("ideal").identity_record("9.9")
    assert ideal == {"name": "sim-ideal", "serial": None, "software": "9.9"}
    host = RigConfig.from_dict({"ports": PORTS}).identity_name()
    assert host == re.sub(r"[^A-Za-z0-9._-]+", "-", socket.gethostname()).strip("-._")[:64] or host == "rig"
    named = RigConfig.from_dict({"ports": PORTS, "identity": {"name": "cannon-2", "serial": "SN 42"}})
    assert named.identity_record("1") == {"name": "cannon-2", "serial": "SN 42", "software": "1"}
    with pytest.raises(ConfigError, match="identity"):
        RigConfig.from_dict({"ports": PORTS, "identity": {"name": "../x"}})
    with pytest.raises(ConfigError, match="identity"):
        RigConfig.from_dict({"ports": PORTS, "identity": {"nickname": "x"}})


def _certify(tmp_path: Path, *extra: str) -> tuple[int, str, str]:
    (tmp_path / "bat.toml").write_text(GOOD_BAT)
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE)
    argv = ["certify", "--procedure", str(tmp_path / "proc.toml"), "--bat", str(tmp_path / "bat.toml")]
    return cli(*argv, "--sim", "ideal", "--db", str(tmp_path / "r.db"), *extra)


def test_a_run_records_its_rig_is_signed_when_sealed_and_listed_by_rig(tmp_path: Path) -> None:
    db = str(tmp_path / "r.db")
    assert cli("keys", "create", "--rig", "sim-ideal")[0] == 0
    assert cli("keys", "register", "--db", db, "--rig", "sim-ideal")[0] == 0
    code, _, err = _certify(tmp_path)
    assert code in (0, 1), err
    with Store.open(db) as store:
        (run,) = store.runs()
        (created,) = store.entries(run.run_id, kinds=["RunCreated"])
        sealed = store.entries(run.run_id)[-1]
        signed = store.entries(None, kinds=["RunSigned"])
        entries = store.entries()
    recorded = created.payload["meta"]["rig"]
    assert recorded == {"name": "sim-ideal", "serial": None, "software": rig.__version__}
    assert sealed.kind == "RunStatusChanged" and sealed.payload["status"] == "finished"
    assert [(s.payload["run_id"], s.payload["anchor"]) for s in signed] == [
        (run.run_id, {"chain_seq": sealed.chain_seq, "hash": sealed.hash})
    ]
    # right after the seal: only the lab chain's seal anchor (format 2) comes between
    assert [e.kind for e in entries if sealed.seq < e.seq <= signed[0].seq] == ["RunSealed", "RunSigned"]
    code, out, _ = cli("verify", "--db", db)
    assert code == 0 and "1 runs signed, 0 unsigned, 0 bad" in out
    rows = json.loads(cli("runs", "--db", db, "--rig", "sim-ideal", "--json")[1])
    assert [(r["run_id"], r["rig"]["name"]) for r in rows] == [(run.run_id, "sim-ideal")]
    assert json.loads(cli("runs", "--db", db, "--rig", "sim-lab", "--json")[1]) == []


def test_no_key_nothing_signed_and_a_key_open_to_others_stops_a_run_before_it_starts(tmp_path: Path) -> None:
    code, _, err = _certify(tmp_path)
    assert code in (0, 1), err
    with Store.open(tmp_path / "r.db") as store:
        assert store.entries(None, kinds=["RunSigned"]) == [] and len(store.runs()) == 1
    assert "0 runs signed, 1 unsigned, 0 bad" in cli("verify", "--db", str(tmp_path / "r.db"))[1]
    cli("keys", "create", "--rig", "sim-ideal")
    (Path(os.environ["RIG_KEY_DIR"]) / "sim-ideal.key").chmod(0o644)
    refused(_certify(tmp_path), "open to group/others")
    with Store.open(tmp_path / "r.db") as store:
        assert len(store.runs()) == 1  # nothing recorded for the refused run


def test_ending_a_run_signs_it(tmp_path: Path) -> None:
    cli("keys", "create", "--rig", "cannon-2")
    assert cli("keys", "register", "--db", str(tmp_path / "r.db"), "--rig", "cannon-2")[0] == 0
    with Store.open(tmp_path / "r.db") as store:
        store.register_bat("B1", {"id": "B1"})
        meta = {"rig": {"name": "cannon-2", "serial": None, "software": "x"}}
        run_id = store.create_run("bbcor", "B1", meta)
        end_run(store, run_id, Signoff("ann", "bat cracked"))
        (signed,) = store.entries(None, kinds=["RunSigned"])
        last = store.entries(run_id)[-1]
        assert last.payload["status"] == "aborted"
        assert signed.payload["anchor"] == {"chain_seq": last.chain_seq, "hash": last.hash}
        assert store.verify().runs_signed == 1


def test_old_runs_show_no_rig(tmp_path: Path) -> None:
    db = tmp_path / "log-v1.db"
    shutil.copyfile(FIXTURES / "log-v1.db", db)
    rows = json.loads(cli("runs", "--db", str(db), "--json")[1])
    assert len(rows) == 3 and all(r["rig"] is None for r in rows)
    assert json.loads(cli("runs", "--db", str(db), "--rig", "sim-ideal", "--json")[1]) == []
    code, out, _ = cli("verify", "--db", str(db))
    assert code == 0 and "0 runs signed, 3 unsigned, 0 bad" in out  # all sealed, their rig unknown
    table = cli("runs", "--db", str(db))[1]
    assert table.count("| -   |") == 3, table  # piped: plain ASCII rules


def _sealed_unsigned(db: Path, rig_meta: dict | None = None) -> str:
    """A sealed run of rig cannon-2 (registered key) whose signature never came (killed in between)."""
    assert cli("keys", "create", "--rig", "cannon-2")[0] == 0
    assert cli("keys", "register", "--db", str(db), "--rig", "cannon-2")[0] == 0
    with Store.open(db) as store:
        store.register_bat("B1", {"id": "B1"})
        meta = {} if rig_meta is None else {"rig": rig_meta}
        run_id = store.create_run("bbcor", "B1", meta)
        store.append(run_id, "ShotMeasured", {"shot": 0})
        store.set_run_status(run_id, "finished", "PASS")
    return run_id


def test_keys_sign_signs_a_sealed_run_whose_signature_never_came(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    run_id = _sealed_unsigned(db, {"name": "cannon-2", "serial": None, "software": "x"})
    code, out, _ = cli("verify", "--db", str(db))
    assert code == 1 and "not signed" in out and "0 runs signed, 1 unsigned, 0 bad" in out
    refused(cli("keys", "sign", "--db", str(db), "--run", run_id, "--rig", "other"), "no key")
    code, _, err = cli("keys", "sign", "--db", str(db), "--run", run_id[:8])
    assert code == 0, err
    code, out, _ = cli("verify", "--db", str(db))
    assert code == 0 and "1 runs signed, 0 unsigned, 0 bad" in out
    refused(cli("keys", "sign", "--db", str(db), "--run", run_id), "signed already")


def test_keys_sign_refuses_a_running_run_a_run_of_no_rig_and_an_altered_store(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    old = _sealed_unsigned(db)  # from before identities: no rig recorded
    refused(cli("keys", "sign", "--db", str(db), "--run", old), "records no rig", "--rig")
    with Store.open(db) as store:
        running = store.create_run("bbcor", "B1", {})
    refused(cli("keys", "sign", "--db", str(db), "--run", running, "--rig", "cannon-2"), "not sealed")
    conn = sqlite3.connect(db, isolation_level=None)
    conn.execute("DROP TRIGGER log_no_update")
    conn.execute("UPDATE log SET payload = '{\"shot\":1}' WHERE kind = 'ShotMeasured'")
    conn.close()
    refused(cli("keys", "sign", "--db", str(db), "--run", old, "--rig", "cannon-2"), "does not verify")
    with Store.open(db) as store:
        assert store.entries(None, kinds=["RunSigned"]) == []


def _signed_runs(db: Path) -> list[str]:
    with Store.open(db) as store:
        return [e.payload["run_id"] for e in store.entries(None, kinds=["RunSigned"])]


def test_a_simulated_run_names_its_rig_and_is_signed_only_in_a_store_that_registered_its_key(
    tmp_path: Path,
) -> None:
    """A sim-ideal key created once signed every later simulated run of the user in any store, and
    nothing said which rig a simulated run is recorded on (the README's keys sequence missed it)."""
    assert cli("keys", "create", "--rig", "sim-ideal")[0] == 0
    code, _, err = _certify(tmp_path)
    assert code in (0, 1), err
    assert "rig sim-ideal (simulated)" in err
    assert "not signed" in err and "rig keys register --db" in err and "--rig sim-ideal" in err
    assert _signed_runs(tmp_path / "r.db") == []
    assert cli("keys", "register", "--db", str(tmp_path / "r.db"), "--rig", "sim-ideal")[0] == 0
    code, _, err = _certify(tmp_path)
    assert code in (0, 1) and "not signed" not in err and "signed with rig sim-ideal's key" in err
    assert len(_signed_runs(tmp_path / "r.db")) == 1


def _sim_named(name: str) -> RigConfig:
    config = sim_config("ideal")
    return config.model_copy(update={"identity": config.identity.model_copy(update={"name": name})})


def _run_library(tmp_path: Path, config: RigConfig, **kw: object) -> tuple[str, list[str]]:
    """A quick certification through rig.certification.certify; (run id, the RigNamed lines)."""
    from rig.certification import certify
    from rig.core.bat import BatSpec
    from rig.protocols.procedure import Procedure

    (tmp_path / "bat.toml").write_text(GOOD_BAT)
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE)
    said: list[str] = []

    def hear(event: object) -> None:
        if getattr(event, "kind", "") == "RigNamed":
            said.append(str(getattr(event, "data", "")))

    with Store.open(tmp_path / "r.db") as store:
        bat, proc = BatSpec.load(tmp_path / "bat.toml"), Procedure.load(tmp_path / "proc.toml")
        outcome = certify(store, proc, bat, config, subscribers=[hear], **kw)
    return outcome.run_id, said


def test_a_simulated_run_is_never_signed_with_a_real_rigs_key_unless_asked(tmp_path: Path) -> None:
    cli("keys", "create", "--rig", "cannon-2")
    assert cli("keys", "register", "--db", str(tmp_path / "r.db"), "--rig", "cannon-2")[0] == 0
    _, said = _run_library(tmp_path, _sim_named("cannon-2"))
    assert _signed_runs(tmp_path / "r.db") == []
    assert len(said) == 1 and "cannon-2" in said[0] and "not signed" in said[0]
    asked, said = _run_library(tmp_path, _sim_named("cannon-2"), sign_simulated=True)
    assert _signed_runs(tmp_path / "r.db") == [asked] and "not signed" not in said[0]


def test_signing_with_a_key_the_store_does_not_list_is_said_at_the_start_and_by_verify(
    tmp_path: Path,
) -> None:
    """Such a signature cannot be checked: verify counted the run unsigned without a word."""
    cli("keys", "create", "--rig", "cannon-2")
    run_id, said = _run_library(tmp_path, _sim_named("cannon-2"), sign_simulated=True)
    assert _signed_runs(tmp_path / "r.db") == [run_id]
    assert "warning" in said[0] and "not registered" in said[0] and "rig keys register" in said[0]
    code, out, _ = cli("verify", "--db", str(tmp_path / "r.db"))
    assert code == 0 and "0 runs signed, 1 unsigned, 0 bad" in out
    assert "1 unsigned run carries a signature by a key this store does not list (rig cannon-2)" in out
    assert cli("keys", "register", "--db", str(tmp_path / "r.db"), "--rig", "cannon-2")[0] == 0
    assert "1 runs signed, 0 unsigned, 0 bad" in cli("verify", "--db", str(tmp_path / "r.db"))[1]


def test_keys_sign_with_a_key_the_store_does_not_list_warns(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    with Store.open(db) as store:
        store.register_bat("B1", {"id": "B1"})
        run_id = store.create_run(
            "bbcor", "B1", {"rig": {"name": "cannon-3", "serial": None, "software": "x"}}
        )
        store.set_run_status(run_id, "finished", "PASS")
    cli("keys", "create", "--rig", "cannon-3")
    code, out, err = cli("keys", "sign", "--db", str(db), "--run", run_id)
    assert code == 0 and f"run {run_id} signed" in out
    assert "warning" in err and "not registered" in err and "rig keys register --db" in err
