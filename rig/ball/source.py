"""CCOR points from the record store's ball-lot tests (`rig model fit-ball --db STORE --lot LOT`).

The store keeps a lot's measurements as the `lot_result` of each finished ball-test run
(`Store.ball_lot(lot_id) -> (BallLot, [LotResult])`, docs/ball-tests.md). The points fitted are the
valid hits of the lot's finished `ccor` tests (the rigid cylinder; a `ball-cor` result is a COR
on the flat plate at one speed, not CCOR, and is left out): each hit's speed at the cylinder's
face, its CCOR, its standard uncertainty and its ball, oldest run first. The runs they come from
are returned with them, for the ball file's provenance. An unknown lot and a lot without a
finished `ccor` test are refused in one line naming the lot and the cause.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from rig.ball.data import CcorData, CcorPoint, check_point
from rig.core.ball import LotResult
from rig.core.errors import RigError
from rig.store import Store

PROCEDURE = "ccor"


class NoBallTests(RigError):
    """The store holds no finished CCOR test of the lot asked for."""


@dataclass(frozen=True)
class StoreCcor:
    """The lot's CCOR points, the bytes their provenance hashes, and the runs that measured them."""

    data: CcorData
    runs: tuple[str, ...]  # the ccor test runs the points come from, oldest first


def ccor_results(store: Store, lot: str) -> list[LotResult]:
    """The lot's finished `ccor` results, oldest first; UnknownRecord (naming the known lots) for an
    unregistered lot, NoBallTests when the lot has no `ccor` result with points."""
    _, results = store.ball_lot(lot)
    ccor = [r for r in results if r.procedure == PROCEDURE and r.points]
    if not ccor:
        others = sorted({r.procedure for r in results})
        held = f" (its results: {', '.join(others)} only)" if others else " (no ball test of it has finished)"
        raise NoBallTests(
            f"ball lot {lot!r} has no finished {PROCEDURE} test{held};"
            f" run rig balls test --procedure {PROCEDURE} --lot {lot} first"
        )
    return ccor


def ccor_data_from_store(store: Store, lot: str, name: str) -> StoreCcor:
    """The points of `lot`'s `ccor` tests in `store`, named `name` in messages and provenance.

    The bytes hashed are the points as canonical JSON (sorted keys, no spaces): one object per hit
    with its run id, shot index, ball id, speed_m_s, ccor and u_ccor, in the store's order.
    """
    points, rows = [], []
    results = ccor_results(store, lot)
    for result in results:
        for hit in result.points:
            where = f"{name}: run {result.run_id}, shot {hit.shot}"
            points.append(check_point(CcorPoint(hit.speed_m_s, hit.cor, hit.u, hit.ball_id, where)))
            rows.append(
                {
                    "run_id": result.run_id,
                    "shot": hit.shot,
                    "ball_id": hit.ball_id,
                    "speed_m_s": hit.speed_m_s,
                    "ccor": hit.cor,
                    "u_ccor": hit.u,
                }
            )
    blob = json.dumps(rows, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()
    return StoreCcor(CcorData(tuple(points), blob, name), tuple(r.run_id for r in results))
