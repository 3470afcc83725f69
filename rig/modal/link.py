"""A bat's record links its modal result: stored as a rig-level 'ModalResult' entry, used by certify.

The store is passed in (anything with `append`, `entries` and `bats`, i.e. rig.store.Store), so
this module needs nothing above rig.core. The bat file's own hoop_hz, if it has one, wins; a bat
without one takes hoop_hz from the latest ModalResult recorded for its id.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.modal.errors import NoHoopMode
from rig.modal.recording import read_recording_bytes

if TYPE_CHECKING:  # only named in annotations: certify needs the link, not the analysis (scipy)
    from rig.modal.analysis import ModalResult

MODAL_RESULT_KIND = "ModalResult"


class _Entry(Protocol):
    payload: dict[str, Any]


class ModalLog(Protocol):
    """What this module needs of the record store."""

    def append(self, run_id: str | None, kind: str, payload: dict[str, Any]) -> Any: ...

    def entries(
        self, run_id: str | None = None, kinds: Iterable[str] | None = None, after_seq: int = 0
    ) -> Sequence[Any]: ...

    def bats(self) -> dict[str, dict[str, Any]]: ...


def sha256_of(path: str | Path) -> str:
    """Hex sha256 of a recording file's bytes (read within the recordings' bound)."""
    return hashlib.sha256(read_recording_bytes(path)).hexdigest()


def modal_payload(result: ModalResult, bat_id: str, path: str | Path) -> dict[str, Any]:
    """The ModalResult entry's payload: bat, file (name and sha256), hoop and bending frequencies."""
    hoop = result.hoop
    if hoop is None:
        raise NoHoopMode(
            f"{path}: no hoop mode identified, nothing to link to bat {bat_id}"
            + (f" ({result.warnings[-1]})" if result.warnings else "")
        )
    return {
        "bat_id": bat_id,
        "file": Path(path).name,
        "sha256": sha256_of(path),
        "hoop_hz": hoop.frequency_hz,
        "hoop_u_hz": hoop.u_hz,
        "hoop_expanded_uncertainty_hz": hoop.expanded_uncertainty_hz,
        "coverage_k": 2.0,
        "bending_hz": result.bending_hz,
        "modes": [m.as_dict() for m in result.modes],
        "n_hits": result.n_hits,
        "window_s": result.window_s,
        "resolution_hz": result.resolution_hz,
    }


def record_modal_result(
    store: ModalLog, bat_id: str, result: ModalResult, path: str | Path
) -> dict[str, Any]:
    """Append a rig-level ModalResult entry for `bat_id`; returns its payload."""
    payload = modal_payload(result, bat_id, path)
    store.append(None, MODAL_RESULT_KIND, payload)
    return payload


def latest_modal_result(store: ModalLog, bat_id: str) -> dict[str, Any] | None:
    """Payload of the newest ModalResult entry for `bat_id`, or None."""
    found = [e.payload for e in store.entries(kinds=[MODAL_RESULT_KIND]) if e.payload.get("bat_id") == bat_id]
    return found[-1] if found else None


def with_measured_hoop(store: ModalLog, bat: BatSpec) -> BatSpec:
    """`bat` with hoop_hz from its latest ModalResult when the bat file gives none."""
    if bat.hoop_hz is not None:
        return bat
    latest = latest_modal_result(store, bat.id)
    if latest is None or latest.get("hoop_hz") is None:
        return bat
    measured = bat.model_copy(update={"hoop_hz": float(latest["hoop_hz"])})
    registered = store.bats().get(bat.id)
    if registered is not None and registered != measured.registered():
        raise ConfigError(
            f"bat {bat.id} was registered with hoop_hz {registered.get('hoop_hz')} before its modal result"
            f" ({measured.hoop_hz:.1f} Hz from {latest.get('file')}); a registered bat's properties are"
            f" fixed: certify it under a new id to use the measured hoop frequency",
            source="bat file",
        )
    return measured
