"""Canonical JSON, the chain hash and the base64 helpers: the byte-exact parts of the record."""

from __future__ import annotations

import base64
import binascii
import hashlib
import json
import math
import re
from typing import Any

from rig.core.errors import RecordRefused, StoreError

GENESIS_HASH = "0" * 64
"""prev_hash of the first entry (seq 1)."""

# Kinds end up in reports and CLI filters: keep them to plain identifiers.
_KIND = re.compile(r"[A-Za-z][A-Za-z0-9_.]{0,63}")


def canonical_json(value: Any) -> str:
    """One fixed text for a JSON-able value: sorted keys, no spaces, ASCII only, no NaN/inf.

    Only dict (str keys), list, tuple, str, int, float, bool and None are accepted, so that
    decoding the text gives back an equal value (tuples come back as lists).
    """
    _check_jsonable(value, "payload")
    # ensure_ascii: the stored text is pure ASCII, so its bytes do not depend on any encoder.
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def decode_payload(text: str) -> dict[str, Any]:
    """Decode a stored payload (the inverse of canonical_json for a dict)."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise StoreError(f"payload is not valid JSON: {exc}") from None
    if not isinstance(value, dict):
        raise StoreError(f"payload is a JSON {type(value).__name__}, not an object")
    return value


def check_payload(payload: object) -> str:
    """Canonical JSON of an entry's payload, which must be a dict."""
    if not isinstance(payload, dict):
        raise RecordRefused(f"payload must be a dict, not {type(payload).__name__}")
    return canonical_json(payload)


def check_kind(kind: object) -> str:
    """The kind itself if it is a plain identifier (letter first; letters, digits, '_', '.')."""
    if not isinstance(kind, str) or not _KIND.fullmatch(kind):
        raise RecordRefused(f"kind {kind!r}: must be a letter then up to 63 letters, digits, '_' or '.'")
    return kind


def entry_hash(prev_hash: str, seq: int, run_id: str | None, kind: str, t_utc: str, payload: str) -> str:
    """sha256 hex of one entry, chained to its predecessor by `prev_hash`.

    The fields are hashed as the canonical JSON array [prev_hash, seq, run_id, kind, t_utc,
    payload] rather than concatenated, so no two different rows share a hash input (with plain
    concatenation, moving a character from one field to the next would keep the hash).
    """
    material = json.dumps(
        [prev_hash, seq, run_id, kind, t_utc, payload], separators=(",", ":"), ensure_ascii=True
    )
    return hashlib.sha256(material.encode("ascii")).hexdigest()


def encode_bytes(data: bytes | bytearray | memoryview) -> str:
    """Raw bytes (e.g. serial traffic) as standard base64 text, to put in a payload."""
    return base64.b64encode(bytes(data)).decode("ascii")


def decode_bytes(text: str) -> bytes:
    """The bytes back from `encode_bytes` text; refuses anything that is not strict base64."""
    try:
        return base64.b64decode(text.encode("ascii"), validate=True)
    except (binascii.Error, UnicodeEncodeError, AttributeError) as exc:
        raise RecordRefused(f"not base64 text: {exc}") from None


def _check_jsonable(value: Any, where: str) -> None:
    # Walk first so that the error names the offending key, which json.dumps would not.
    if value is None or isinstance(value, str | bool | int):
        return
    if isinstance(value, float):
        if not math.isfinite(value):
            raise RecordRefused(f"{where} = {value!r}: NaN and infinities have no JSON form")
        return
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                raise RecordRefused(f"{where}: key {key!r} is not a str")
            _check_jsonable(item, f"{where}.{key}")
        return
    if isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _check_jsonable(item, f"{where}[{i}]")
        return
    hint = " (use encode_bytes for raw bytes)" if isinstance(value, bytes | bytearray | memoryview) else ""
    raise RecordRefused(f"{where}: {type(value).__name__} is not JSON-able{hint}")
