"""CCOR points from the record store's ball-lot tests (`rig model fit-ball --db STORE --lot LOT`).

The store side (ball lots and their `ccor` tests) is built separately. This module reads what a
store offers through one method, `store.ball_test_points(lot, procedure)`: an iterable of
mappings with `speed_m_s`, `ccor` and optionally `u_ccor` and `ball_id` (one per ball and speed,
the valid shots of the lot's finished `ccor` tests). A store without it, or a lot without such
points, is refused with one line naming the cause.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

from rig.ball.data import CcorData, CcorPoint, check_point
from rig.core.errors import ConfigError, RigError

PROCEDURE = "ccor"


class NoBallTests(RigError):
    """The store holds no CCOR tests of the lot asked for."""


def _point(row: Mapping[str, Any], where: str) -> CcorPoint:
    def num(key: str) -> float | None:
        value = row.get(key)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ConfigError(f"{key} {value!r} is not a finite number", source=where)
        return float(value)

    speed, ccor = num("speed_m_s"), num("ccor")
    if speed is None or ccor is None:
        raise ConfigError("a ccor test point lacks speed_m_s or ccor", source=where)
    ball = row.get("ball_id")
    return check_point(CcorPoint(speed, ccor, num("u_ccor"), None if ball is None else str(ball), where))


def ccor_points_from_store(store: Any, lot: str) -> list[CcorPoint]:
    """The CCOR points of `lot`'s tests in `store`; NoBallTests when there are none."""
    reader = getattr(store, "ball_test_points", None)
    if not callable(reader):
        raise NoBallTests("the store has no ball-lot tests (this store holds no ball lots)")
    rows: Iterable[Mapping[str, Any]] = reader(lot, PROCEDURE)
    points = [_point(r, f"store: lot {lot}, point {i + 1}") for i, r in enumerate(rows)]
    if not points:
        raise NoBallTests(f"the store has no {PROCEDURE} tests of ball lot {lot!r}")
    return points


def ccor_data_from_store(store: Any, lot: str, name: str) -> CcorData:
    """The points with the bytes their provenance hashes: the rows as canonical JSON (sorted keys)."""
    points = ccor_points_from_store(store, lot)
    rows = [
        {"speed_m_s": p.speed_m_s, "ccor": p.ccor, "u_ccor": p.u_ccor, "ball_id": p.ball_id} for p in points
    ]
    blob = json.dumps(rows, sort_keys=True, separators=(",", ":")).encode()
    return CcorData(tuple(points), blob, name)
