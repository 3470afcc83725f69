"""Ball lots in the store: registered on the lab chain, measured by ball-test runs.

A lot is a lab-level 'BallLotRegistered' entry (the register file's content, validated); its
results are not written separately: each one is the `lot_result` of a finished ball-test run's
RunFinished, derived from that run's shots and covered by that run's own chain and signature.
So `rig verify` checks a lot's results as far as it checks their runs, and a result can be
recomputed from its run's shots at any time.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rig.core import events as ev
from rig.core.errors import RecordRefused, UnknownRecord
from rig.core.outcomes import RunVerdict
from rig.store._codec import decode_payload
from rig.store._records import BALL_LAW_RECORDED, BALL_LOT_REGISTERED
from rig.store._rows import known_ids

if TYPE_CHECKING:  # the lot models need pydantic: imported when a lot is read, not with the store
    from rig.core.ball import BallLot, LotResult

CcorPoint = tuple[float, float, float, str]  # (speed_m_s, ccor, u_ccor, ball_id)


def registered(conn: Any) -> dict[str, BallLot]:
    """Every registered lot by id, in registration order."""
    rows = conn.execute("SELECT payload FROM log WHERE kind = ? ORDER BY seq", (BALL_LOT_REGISTERED,))
    from rig.core.ball import BallLot

    lots: dict[str, BallLot] = {}
    for (payload,) in rows:
        data = decode_payload(payload)
        lots.setdefault(data["lot_id"], BallLot.model_validate(data["lot"]))
    return lots


@dataclass(frozen=True)
class RecordedLaw:
    """A lot's ball law as recorded: the ball file's exact text, its sha256, when, and the entry."""

    lot_id: str
    text: str
    sha256: str
    t_utc: str
    seq: int

    @property
    def intact(self) -> bool:
        """Whether the text is still the one its recorded sha256 names."""
        return law_sha256(self.text) == self.sha256


def laws(conn: Any, lot_id: str) -> list[RecordedLaw]:
    """The ball laws recorded for `lot_id`, oldest first (the last is the lot's ball law)."""
    sql = "SELECT seq, payload, t_utc FROM log WHERE kind = ? ORDER BY seq"
    rows = conn.execute(sql, (BALL_LAW_RECORDED,))
    out = []
    for seq, payload, t_utc in rows:
        data = decode_payload(payload)
        if data.get("lot_id") == lot_id:
            out.append(RecordedLaw(lot_id, str(data["text"]), str(data["sha256"]), str(t_utc), int(seq)))
    return out


def law_sha256(text: str) -> str:
    """The sha256 of a ball file's text, as recorded (the file's bytes in UTF-8)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def checked_lot(lot: BallLot | dict[str, Any]) -> dict[str, Any]:
    """The lot as the store keeps it (validated); RecordRefused naming the first bad field."""
    from pydantic import ValidationError

    from rig.core.ball import BallLot

    try:
        return BallLot.model_validate(lot).model_dump(mode="json")
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(lot)"
        raise RecordRefused(f"lot.{where}: {first['msg']}") from None


def unknown(lot_id: str, lots: dict[str, BallLot]) -> UnknownRecord:
    """The error for a lot id the store does not hold."""
    return UnknownRecord(f"no ball lot {lot_id!r}; {known_ids('lots', list(lots))}")


def results(store: Any, lot_id: str) -> list[LotResult]:
    """The lot's measured results, oldest first: one per finished ball-test run of the lot."""
    from rig.core.ball import BALL_TESTS, LotResult

    found = []
    for run in store.runs():
        if run.procedure not in BALL_TESTS or run.status != "finished":
            continue
        for entry in store.entries(run.run_id, kinds=[ev.RUN_FINISHED]):
            v = RunVerdict.from_payload(entry.payload, ev.RUN_FINISHED)
            if v.lot == lot_id and isinstance(v.lot_result, dict):
                found.append(LotResult.model_validate({**v.lot_result, "run_id": run.run_id}))
    return found


def points(found: list[LotResult]) -> list[CcorPoint]:
    """The valid hits of the lot's ccor tests as (speed_m_s, ccor, u_ccor, ball_id)."""
    return [(p.speed_m_s, p.cor, p.u, p.ball_id) for r in found if r.procedure == "ccor" for p in r.points]


__all__ = [
    "BALL_LAW_RECORDED",
    "BALL_LOT_REGISTERED",
    "RecordRefused",
    "RecordedLaw",
    "checked_lot",
    "law_sha256",
    "laws",
    "points",
    "registered",
    "results",
    "unknown",
]
