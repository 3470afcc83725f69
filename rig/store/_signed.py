"""Signed run anchors: each RunSigned checked against its rig's registered Ed25519 key.

The hash chain shows that nothing changed since the last entry, but anyone who can write the file
can recompute it. A rig signs the anchor (seq, hash) of each run's last entry with a private key
that never enters the store; the public keys are listed in the log (RigKeyRegistered). A run
rewritten after it was signed no longer matches its anchor, and a new anchor needs the key.
"""

from __future__ import annotations

import base64
import binascii
import dataclasses
import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from rig.store._codec import canonical_json
from rig.store._records import CLOSED_STATUSES, RUN_CREATED, RUN_STATUS_CHANGED, VerifyReport

RIG_KEY_REGISTERED = "RigKeyRegistered"  # rig-level: {rig, public_key (base64 raw), fingerprint}
RUN_SIGNED = "RunSigned"  # rig-level: {run_id, rig, fingerprint, anchor: {seq, hash}, signature}
_DECODED = (RUN_CREATED, RUN_STATUS_CHANGED, RIG_KEY_REGISTERED, RUN_SIGNED)


def fingerprint(public_raw: bytes) -> str:
    """A public key's fingerprint: the first 16 hex digits of sha256 over its raw 32 bytes."""
    return hashlib.sha256(public_raw).hexdigest()[:16]


def anchor_message(run_id: str, seq: int, hash_: str, field: str = "seq") -> bytes:
    """The bytes a rig signs: canonical JSON of {"run_id", "seq", "hash"}; in chain format 2 the
    anchor is the run's own chain position, {"run_id", "chain_seq", "hash"}, so that it holds
    wherever the run's records are copied (rig sync)."""
    return canonical_json({"run_id": run_id, field: seq, "hash": hash_}).encode("ascii")


@dataclass(frozen=True)
class RegisteredKey:
    """One RigKeyRegistered entry: valid for its rig from its seq until the rig's next one."""

    rig: str
    fingerprint: str
    public_key: str  # base64 of the raw 32 bytes
    seq: int
    t_utc: str

    def verifies(self, signature: bytes, message: bytes) -> bool:
        """Whether `signature` is this key's Ed25519 signature of `message`."""
        from cryptography.exceptions import InvalidSignature  # loaded when a signature is checked
        from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

        try:
            Ed25519PublicKey.from_public_bytes(base64.b64decode(self.public_key)).verify(signature, message)
        except (InvalidSignature, ValueError):
            return False
        return True


def parse_registration(seq: int, t_utc: str, payload: dict[str, Any]) -> RegisteredKey:
    """A RigKeyRegistered payload as a key; ValueError if it is malformed or its fingerprint is wrong."""
    rig, text, claimed = payload.get("rig"), payload.get("public_key"), payload.get("fingerprint")
    if not (isinstance(rig, str) and isinstance(text, str) and isinstance(claimed, str)):
        raise ValueError("rig, public_key and fingerprint must be text")
    try:
        raw = base64.b64decode(text.encode("ascii"), validate=True)
    except (binascii.Error, UnicodeEncodeError):
        raise ValueError("public_key is not base64") from None
    if len(raw) != 32:
        raise ValueError(f"public_key has {len(raw)} bytes, an Ed25519 key has 32")
    if fingerprint(raw) != claimed:
        raise ValueError(f"fingerprint {claimed} is not the key's ({fingerprint(raw)})")
    return RegisteredKey(rig, claimed, text, seq, t_utc)


@dataclass(frozen=True)
class SignatureReport:
    """Sealed runs by signature: signed (valid), unsigned (none) and bad (one fails); what is wrong."""

    signed: int = 0
    unsigned: int = 0
    bad: int = 0
    problems: tuple[str, ...] = ()
    unlisted: tuple[str, ...] = ()  # the rig of each run signed by a key the store does not list


@dataclass
class _Run:
    rig: str | None = None  # the rig name RunCreated recorded (None: an old run)
    last: tuple[int, str] = (0, "")  # seq and hash of its last entry
    last_in_chain: tuple[int | None, str] = (None, "")  # chain_seq and hash of it (chain format 2)
    sealed_at: int | None = None


class SignatureCheck:
    """Feed every log entry in seq order, then `result()`: each RunSigned and each sealed run checked."""

    def __init__(self) -> None:
        self.runs: dict[str, _Run] = {}
        self.keys: dict[str, list[RegisteredKey]] = {}  # rig -> registrations in seq order
        self.signatures: list[tuple[int, dict[str, Any]]] = []
        self.problems: list[str] = []

    def feed(
        self,
        seq: int,
        run_id: str | None,
        kind: str,
        payload: str | None,
        t_utc: str,
        hash_: str,
        chain_seq: int | None = None,
    ) -> None:
        """One entry; `payload` is needed only for RunCreated, RunStatusChanged and the two kinds here."""
        if run_id is not None:
            run = self.runs.setdefault(run_id, _Run())
            run.last = (seq, hash_)
            run.last_in_chain = (chain_seq, hash_)
        if kind not in _DECODED:
            return
        try:
            data = json.loads(payload or "")
            if not isinstance(data, dict):
                raise ValueError("not a JSON object")
        except ValueError:
            if kind in (RIG_KEY_REGISTERED, RUN_SIGNED):
                self.problems.append(f"seq {seq}: {kind} payload unreadable")
            return  # the reserved kinds' payloads are the chain's and the tables' finding
        if kind == RUN_CREATED and run_id is not None:
            meta = data.get("meta")
            rig = meta.get("rig") if isinstance(meta, dict) else None
            name = rig.get("name") if isinstance(rig, dict) else None
            self.runs[run_id].rig = name if isinstance(name, str) else None
        elif kind == RUN_STATUS_CHANGED and run_id is not None:
            if data.get("status") in CLOSED_STATUSES and self.runs[run_id].sealed_at is None:
                self.runs[run_id].sealed_at = seq
        elif kind == RIG_KEY_REGISTERED:
            try:
                key = parse_registration(seq, t_utc, data)
            except ValueError as exc:
                self.problems.append(f"seq {seq}: RigKeyRegistered refused: {exc}")
                return
            self.keys.setdefault(key.rig, []).append(key)
        elif kind == RUN_SIGNED:
            self.signatures.append((seq, data))

    def key_at(self, rig: str, seq: int) -> RegisteredKey | None:
        """The rig's key in force at `seq` (before its first registration: the first one)."""
        keys = self.keys.get(rig, [])
        before = [k for k in keys if k.seq < seq]
        return before[-1] if before else (keys[0] if keys else None)

    def result(self) -> SignatureReport:
        """Counts over sealed (or signed) runs, and every problem found."""
        good: set[str] = set()
        bad: set[str] = set()
        unlisted: dict[str, str] = {}  # run id -> rig: signed, but its rig lists no key to check it
        problems = list(self.problems)
        for seq, data in self.signatures:
            run_id = data.get("run_id")
            why = self._check(seq, data)
            if why is None:
                good.add(str(run_id))
            elif why == "":
                unlisted[str(run_id)] = str(data.get("rig"))
            else:
                problems.append(f"seq {seq}: RunSigned for run {run_id}: {why}")
                if isinstance(run_id, str):
                    bad.add(run_id)
        counts = {"signed": 0, "unsigned": 0, "bad": 0}
        for run_id, run in self.runs.items():
            if run_id in bad:
                counts["bad"] += 1
            elif run_id in good:
                counts["signed"] += 1
            elif run.sealed_at is not None:
                counts["unsigned"] += 1
                key = None if run.rig is None else self.key_at(run.rig, run.sealed_at)
                if key is not None and key.seq < run.sealed_at:
                    problems.append(
                        f"run {run_id} of rig {run.rig} is sealed (seq {run.sealed_at}) but not signed, "
                        f"though the rig had a registered key (seq {key.seq}): a signature was removed?"
                    )
        shown = tuple(rig for run_id, rig in unlisted.items() if run_id not in good | bad)
        return SignatureReport(counts["signed"], counts["unsigned"], counts["bad"], tuple(problems), shown)

    def _check(self, seq: int, data: dict[str, Any]) -> str | None:
        """None if the signature holds; "" if its rig lists no key; else what is wrong."""
        run_id, rig, anchor = data.get("run_id"), data.get("rig"), data.get("anchor")
        fp = data.get("fingerprint")
        if not (isinstance(run_id, str) and isinstance(rig, str) and isinstance(anchor, dict)):
            return "malformed (run_id, rig or anchor missing)"
        field = "chain_seq" if "chain_seq" in anchor else "seq"
        a_seq, a_hash = anchor.get(field), anchor.get("hash")
        if not isinstance(a_seq, int) or isinstance(a_seq, bool) or not isinstance(a_hash, str):
            return "malformed anchor"
        run = self.runs.get(run_id)
        if run is None:
            return "no such run"
        if run.rig is not None and rig != run.rig:
            return f"signed as rig {rig}, but the run was recorded on rig {run.rig}"
        key = self.key_at(rig, seq)
        if key is None:
            return ""
        if fp != key.fingerprint:
            return f"signed with key {fp}, but rig {rig}'s registered key then was {key.fingerprint}"
        try:
            signature = base64.b64decode(str(data.get("signature", "")).encode("ascii"), validate=True)
        except (binascii.Error, UnicodeEncodeError):
            return "signature is not base64"
        if not key.verifies(signature, anchor_message(run_id, a_seq, a_hash, field)):
            return f"the signature does not verify with key {key.fingerprint} (the anchor was changed)"
        actual = run.last if field == "seq" else run.last_in_chain
        if (a_seq, a_hash) != actual:
            return (
                f"signed anchor {a_seq}:{a_hash} is not the run's last entry {actual[0]}:{actual[1]} "
                "(the run was changed after it was signed)"
            )
        return None


def check(conn: Any, engine: str = "sqlite") -> SignatureReport:
    """Check every signature in the log (caller holds a read transaction)."""
    marks = ", ".join("?" * len(_DECODED))

    def raw(column: str) -> str:  # as bytes: a tampered SQLite row may hold invalid UTF-8
        return f"CAST({column} AS BLOB)" if engine == "sqlite" else f"convert_to({column}, 'UTF8')"

    rows = conn.execute(
        f"SELECT seq, {raw('run_id')}, {raw('kind')}, "
        f"CASE WHEN kind IN ({marks}) THEN {raw('payload')} END, "
        f"{raw('t_utc')}, {raw('hash')}, chain_seq "
        "FROM log ORDER BY seq",
        _DECODED,
    )
    checker = SignatureCheck()
    for seq, *columns, chain_seq in rows:
        run_id, kind, payload, t_utc, hash_ = (
            None if c is None else bytes(c).decode("utf-8", errors="replace") for c in columns
        )
        checker.feed(seq, run_id, kind or "", payload, t_utc or "", hash_ or "", chain_seq)
    return checker.result()


def with_signatures(conn: Any, report: VerifyReport, engine: str = "sqlite") -> VerifyReport:
    """`report` with the signature counts and problems added (Store.verify's last step)."""
    signatures = check(conn, engine)
    return dataclasses.replace(
        report,
        ok=report.ok and not signatures.problems,
        problems=report.problems + signatures.problems,
        runs_signed=signatures.signed,
        runs_unsigned=signatures.unsigned,
        runs_bad_signature=signatures.bad,
        unlisted_signatures=signatures.unlisted,
    )


def registered_keys(entries: Iterable[Any]) -> list[RegisteredKey]:
    """The readable RigKeyRegistered entries among `entries` (LogEntry-like), in seq order."""
    keys = []
    for entry in entries:
        if entry.kind == RIG_KEY_REGISTERED:
            try:
                keys.append(parse_registration(entry.seq, entry.t_utc, entry.payload))
            except ValueError:
                continue  # verify names it
    return keys


def run_seal(store: Any, run_id: str) -> dict[str, Any]:
    """One run's seal as its report shows it: whether it is signed, by which rig's key (fingerprint),
    and whether that signature holds in `store` ('valid', 'key not listed' or what is wrong)."""
    entries = sorted(
        [*store.entries(run_id), *store.entries(None, kinds=[RIG_KEY_REGISTERED, RUN_SIGNED])],
        key=lambda e: e.seq,
    )
    checker = SignatureCheck()
    for e in entries:
        checker.feed(e.seq, e.run_id, e.kind, json.dumps(e.payload), e.t_utc, e.hash, e.chain_seq)
    run = checker.runs.get(run_id, _Run())
    mine = [(seq, data) for seq, data in checker.signatures if data.get("run_id") == run_id]
    if not mine:
        return {"signed": False, "rig": run.rig, "sealed": run.sealed_at is not None}
    seq, data = mine[-1]
    why = checker._check(seq, data)
    check = "valid" if why is None else "key not listed in this store" if why == "" else why
    return {
        "signed": True,
        "rig": data.get("rig"),
        "fingerprint": data.get("fingerprint"),
        "signature_seq": seq,
        "check": check,
        "sealed": run.sealed_at is not None,
    }
