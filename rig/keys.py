"""A rig's signing key: create it, keep it private, list its public half in the store, sign runs.

The private key is a PEM file NAME.key (mode 0600) in the key folder: --dir, else $RIG_KEY_DIR,
else ~/.config/rig/keys/. It never enters the store; the store holds only public keys
(RigKeyRegistered) and signatures (RunSigned), checked by `Store.verify` (rig.store._signed).
"""

from __future__ import annotations

import base64
import os
import re
import shlex
import stat
from dataclasses import dataclass
from pathlib import Path

from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from rig.core.config import RIG_NAME_PATTERN, recorded_rig_simulated
from rig.core.errors import ConfigError, RecordRefused
from rig.core.events import RUN_STARTED
from rig.store import LogEntry, Store
from rig.store._records import RUN_CREATED
from rig.store._signed import (
    RIG_KEY_REGISTERED,
    RUN_SIGNED,
    RegisteredKey,
    anchor_message,
    fingerprint,
    registered_keys,
)

KEY_DIR_ENV = "RIG_KEY_DIR"
_NAME = re.compile(RIG_NAME_PATTERN)


def key_dir(given: str | Path | None = None) -> Path:
    """The key folder: `given`, else $RIG_KEY_DIR, else ~/.config/rig/keys."""
    if given:
        return Path(given).expanduser()
    env = os.environ.get(KEY_DIR_ENV)
    return Path(env).expanduser() if env else Path.home() / ".config" / "rig" / "keys"


def check_name(rig: str) -> str:
    """`rig` if it is a valid rig name (it names a file: letters, digits, '.', '_', '-')."""
    if not isinstance(rig, str) or not _NAME.fullmatch(rig):
        raise ConfigError(
            f"rig name {rig!r}: 1-64 letters, digits, '.', '_' or '-', a letter or digit first", "--rig"
        )
    return rig


def key_path(rig: str, directory: str | Path | None = None) -> Path:
    """Where rig `rig`'s private key lives."""
    return key_dir(directory) / f"{check_name(rig)}.key"


@dataclass(frozen=True)
class Signer:
    """A rig's loaded private key."""

    rig: str
    key: Ed25519PrivateKey
    fingerprint: str

    @property
    def public_b64(self) -> str:
        """The public key, base64 of its raw 32 bytes."""
        return base64.b64encode(_public_raw(self.key)).decode("ascii")


def _public_raw(key: Ed25519PrivateKey) -> bytes:
    return key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def create_key(rig: str, directory: str | Path | None = None) -> tuple[Path, str]:
    """A new key pair for `rig`: the private key written 0600 (refused if one exists); (path, fingerprint)."""
    path = key_path(rig, directory)
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    key = Ed25519PrivateKey.generate()
    pem = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    try:  # O_EXCL: never overwrite a key, even one created a moment ago by another process
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise ConfigError(f"{path}: rig {rig} has a key already; it is kept", "rig keys create") from None
    with os.fdopen(fd, "wb") as out:
        out.write(pem)
    return path, fingerprint(_public_raw(key))


def load_signer(rig: str | None, directory: str | Path | None = None) -> Signer | None:
    """Rig `rig`'s key, or None if it has none; a key file open to group/others is refused."""
    if rig is None:
        return None
    path = key_path(rig, directory)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ConfigError(
            f"{path}: the key file is open to group/others (mode {stat.S_IMODE(mode):o}); "
            f"make it private with: chmod 600 {path}",
            "rig key",
        )
    try:
        key = serialization.load_pem_private_key(path.read_bytes(), password=None)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{path}: not a rig key file ({exc})", "rig key") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise ConfigError(f"{path}: not an Ed25519 key", "rig key")
    return Signer(rig, key, fingerprint(_public_raw(key)))


@dataclass(frozen=True)
class Signing:
    """The key that will sign a run at its seal (None: none), and what the operator should hear."""

    signer: Signer | None
    note: str = ""  # '' when there is nothing to say


SIM_PREFIX = "sim-"  # a simulated rig's own name: sim-SCENE (rig.core.config)


def signing_for(
    store: Store,
    rig: str,
    *,
    simulated: bool,
    sign_simulated: bool = False,
    directory: str | Path | None = None,
) -> Signing:
    """Which key signs a run of rig `rig` in `store`, and why (a key open to others: ConfigError).

    A real rig's run is signed with its key. A simulated run measured no bat: it is signed only
    where its simulated rig's key is registered in this store (a key created once does not sign
    every store's simulated runs), and never with a real rig's key unless `sign_simulated`.
    """
    signer = load_signer(rig, directory)
    register = f"rig keys register --db {shlex.quote(store.location)} --rig {rig}"
    if signer is None:
        return Signing(None, "not signed (no key)" if simulated else "")
    listed = [k for k in keys_in(store) if k.rig == rig]
    if simulated and not sign_simulated:
        if not rig.startswith(SIM_PREFIX):
            return Signing(
                None, f"not signed: a simulated run is never signed with rig {rig}'s key unless asked"
            )
        if not listed or listed[-1].fingerprint != signer.fingerprint:
            return Signing(None, f"not signed: rig {rig}'s key is not registered in this store ({register})")
    return Signing(
        signer, unlisted_warning(store, signer) or f"signed with rig {rig}'s key {signer.fingerprint}"
    )


def unlisted_warning(store: Store, signer: Signer) -> str:
    """A warning when `signer`'s key is not the one the store lists for its rig ('' when it is)."""
    listed = [k for k in keys_in(store) if k.rig == signer.rig]
    register = f"rig keys register --db {shlex.quote(store.location)} --rig {signer.rig}"
    if not listed:
        return (
            f"warning: signed with rig {signer.rig}'s key {signer.fingerprint}, which is not registered in "
            f"this store: rig verify counts the run unsigned until {register} lists it"
        )
    if listed[-1].fingerprint != signer.fingerprint:
        return (
            f"warning: signed with rig {signer.rig}'s key {signer.fingerprint}, but this store lists "
            f"{listed[-1].fingerprint} for it: rig verify will report the signature"
        )
    return ""


def recorded_simulated(store: Store, run_id: str) -> bool:
    """Whether a run was recorded on a simulated rig: RigConfig.simulated's rule applied to the rig
    its RunStarted recorded (a sim:// address, or a device marked simulated: an instrument twin)."""
    started = store.entries(run_id, kinds=[RUN_STARTED])
    rig = started[0].payload.get("rig") if started else None
    return isinstance(rig, dict) and recorded_rig_simulated(rig)


def keys_in(store: Store) -> list[RegisteredKey]:
    """Every key registration in the store, oldest first."""
    return registered_keys(store.entries(None, kinds=[RIG_KEY_REGISTERED]))


def register(store: Store, signer: Signer, *, replace: bool = False) -> LogEntry | None:
    """List `signer`'s public key in the store (None if it is already the rig's current key).

    A different key for a rig already registered is refused unless `replace`; the old key stays
    in the log, so that what it signed can still be checked.
    """
    current = [k for k in keys_in(store) if k.rig == signer.rig]
    if current and current[-1].fingerprint == signer.fingerprint:
        return None
    if current and not replace:
        raise RecordRefused(
            f"rig {signer.rig} already has key {current[-1].fingerprint} registered (seq {current[-1].seq}); "
            f"give --replace to register {signer.fingerprint} in its place"
        )
    payload = {"rig": signer.rig, "public_key": signer.public_b64, "fingerprint": signer.fingerprint}
    return store.append(None, RIG_KEY_REGISTERED, payload)


def recorded_rig(store: Store, run_id: str) -> str | None:
    """The rig name a run's RunCreated recorded (None for runs from before rigs were named)."""
    created = store.entries(run_id, kinds=[RUN_CREATED])
    meta = created[0].payload.get("meta") if created else None
    rig = meta.get("rig") if isinstance(meta, dict) else None
    name = rig.get("name") if isinstance(rig, dict) else None
    return name if isinstance(name, str) else None


def sign_run(store: Store, run_id: str, signer: Signer) -> LogEntry:
    """Append RunSigned: `signer`'s signature over the anchor of the run's last entry: its
    (chain_seq, hash) in chain format 2, its (seq, hash) in format 1."""
    last = store.entry(store.run(run_id).last_seq)
    if last is None or last.run_id != run_id:
        raise RecordRefused(f"run {run_id}: its last entry cannot be read; nothing signed")
    # chain format 2: the run's own chain position, which a copy to the lab's store keeps
    field, at = ("chain_seq", last.chain_seq) if store.chain_format == 2 else ("seq", last.seq)
    assert at is not None
    signature = signer.key.sign(anchor_message(run_id, at, last.hash, field))
    payload = {
        "run_id": run_id,
        "rig": signer.rig,
        "fingerprint": signer.fingerprint,
        "anchor": {field: at, "hash": last.hash},
        "signature": base64.b64encode(signature).decode("ascii"),
    }
    return store.append(None, RUN_SIGNED, payload)


def parse_trusted(texts: list[str]) -> dict[str, set[str]]:
    """RIG:FINGERPRINT pins (kept by the lab outside the store) as {rig: {fingerprints}}."""
    pins: dict[str, set[str]] = {}
    for text in texts:
        rig, _, fp = text.partition(":")
        if not _NAME.fullmatch(rig) or not re.fullmatch(r"[0-9a-f]{16}", fp):
            raise ConfigError(
                f"{text!r}: expected RIG:FINGERPRINT (a rig name, a colon, 16 lowercase hex digits)",
                "--trusted-key",
            )
        pins.setdefault(rig, set()).add(fp)
    return pins


def untrusted(keys: list[RegisteredKey], pins: dict[str, set[str]]) -> list[str]:
    """Each registration of a pinned rig whose key is not pinned, and each pinned rig with no key."""
    problems = [
        f"seq {k.seq}: rig {k.rig}'s registered key {k.fingerprint} is not a trusted one "
        f"({', '.join(sorted(pins[k.rig]))}): a key was replaced in the store?"
        for k in keys
        if k.rig in pins and k.fingerprint not in pins[k.rig]
    ]
    listed = {k.rig for k in keys}
    missing = sorted(pins.keys() - listed)
    problems += [f"rig {rig}: no key registered, though a trusted one was given" for rig in missing]
    return problems


def sign_sealed(store: Store, run_id: str, signer: Signer) -> LogEntry:
    """Sign a sealed run that has no signature (killed between seal and signature, or sealed before
    the rig had a key); refused unless the rest of the store verifies, so nothing altered is signed."""
    run = store.run(run_id)
    if run.status == "running":
        raise RecordRefused(f"run {run_id} is not sealed: it is signed when it is finished or ended")
    recorded = recorded_rig(store, run_id)
    if recorded is not None and recorded != signer.rig:
        raise RecordRefused(f"run {run_id} was recorded on rig {recorded}, not {signer.rig}")
    done = [e.seq for e in store.entries(None, kinds=[RUN_SIGNED]) if e.payload.get("run_id") == run_id]
    if done:
        raise RecordRefused(f"run {run_id} is signed already (seq {done[0]})")
    others = [p for p in store.verify().problems if not (run_id in p and "not signed" in p)]
    if others:
        raise RecordRefused(f"the store does not verify ({others[0]}); nothing signed")
    return sign_run(store, run_id, signer)
