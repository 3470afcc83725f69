"""A run written entry by entry with chosen values, and the view rows those values must give.

The expected rows are written out by hand from the entries below, not computed by any code
under test: they check the views (and `rig export`) against what the log says.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

from rig.store import Store

RIG = {"name": "RIG-A", "serial": "SN-7", "software": "0.1.0"}
BAT = "HAND-1"


def _measured(index: int, metric: float, u: float, v_in: float, v_out: float, codes: list[str]) -> dict:
    reasons = [{"code": c, "invalidates": True, "message": c.lower()} for c in codes]
    return {
        "index": index,
        "metric": metric,
        "u": u,
        "inbound_speed_m_s": v_in,
        "rebound_speed_m_s": v_out,
        "reasons": reasons,
        "valid": not codes,
    }


def build(store: Store) -> str:
    """Write the hand-made run (closed, PASS) into `store`; returns its id."""
    store.register_bat(BAT, {"id": BAT})
    run = store.create_run("bbcor", BAT, {"procedure": "hand", "rig": RIG})
    add = store.append

    def request(index: int, purpose: str, loc: float) -> None:
        add(run, "ShotRequested", {"index": index, "purpose": purpose, "location_in": loc})

    request(1, "scan", 5.0)  # valid
    add(run, "ShotFired", {"index": 1, "crossings": []})
    add(run, "ShotMeasured", _measured(1, 0.451, 0.0011, 60.81, 12.07, []))
    request(2, "scan", 5.5)  # valid, then overruled by the operator
    add(run, "ShotFired", {"index": 2, "crossings": []})
    add(run, "ShotMeasured", _measured(2, 0.462, 0.0012, 60.79, 12.31, []))
    add(run, "ShotOverruled", {"index": 2, "reason": "scuffed ball", "who": "ann"})
    request(3, "valid", 6.0)  # rejected with two reasons
    add(run, "ShotFired", {"index": 3, "crossings": []})
    codes = ["SPEED_OUT_OF_TOLERANCE", "MISSED_GATE"]
    add(run, "ShotRejected", _measured(3, 0.473, 0.0013, 59.9, 12.5, codes))
    request(4, "valid", 6.0)  # fired, then lost
    add(run, "ShotFired", {"index": 4, "crossings": []})
    add(run, "ShotLost", {"index": 4, "reason": "gates unplugged"})
    request(5, "valid", 6.0)  # lost before firing: not a fired shot, no row
    add(run, "ShotLost", {"index": 5, "reason": "cannon misfire"})
    request(6, "valid", 6.5)  # fired, no outcome recorded (yet)
    add(run, "ShotFired", {"index": 6, "crossings": []})
    verdict = {"verdict": "PASS", "metric": "bbcor", "mean": 0.455, "U": 0.0021, "coverage_k": 2.0}
    add(run, "RunFinished", verdict)
    store.set_run_status(run, "finished", "PASS")
    return run


def forge_after_seal(path: Path, run_id: str) -> None:
    """Append to the closed run with plain SQL, as a tamperer would: a shot and a FAIL verdict."""
    conn = sqlite3.connect(path)
    try:
        seq, prev = conn.execute("SELECT seq, hash FROM log ORDER BY seq DESC LIMIT 1").fetchone()
        rows = [
            ("ShotFired", '{"crossings":[],"index":1}'),
            ("ShotRejected", '{"index":1,"metric":0.9,"reasons":[{"code":"FORGED"}],"valid":false}'),
            ("RunFinished", '{"U":0.1,"coverage_k":2.0,"mean":0.9,"verdict":"FAIL"}'),
            ("RunStatusChanged", '{"status":"finished","verdict":"FAIL"}'),
        ]
        for i, (kind, payload) in enumerate(rows, start=1):
            conn.execute(
                "INSERT INTO log (seq, run_id, kind, payload, t_utc, prev_hash, hash) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (seq + i, run_id, kind, payload, "2030-01-01T00:00:00.000000+00:00", prev, f"{seq + i:064x}"),
            )
            prev = f"{seq + i:064x}"
        conn.commit()
    finally:
        conn.close()


def expected_shots(run_id: str, fired_utc: dict[int, str]) -> list[dict[str, Any]]:
    """The `shots` rows of the hand-made run, in shot order (t_utc: its ShotFired entries' times)."""
    common = {"run_id": run_id, "rig": "RIG-A", "bat_id": BAT}
    rows = [
        (1, "scan", 5.0, 60.81, 12.07, 0.451, 0.0011, True, ""),
        (2, "scan", 5.5, 60.79, 12.31, 0.462, 0.0012, False, "OPERATOR_REJECTED"),
        (3, "valid", 6.0, 59.9, 12.5, 0.473, 0.0013, False, "SPEED_OUT_OF_TOLERANCE,MISSED_GATE"),
        (4, "valid", 6.0, None, None, None, None, False, "LOST"),
        (6, "valid", 6.5, None, None, None, None, None, ""),
    ]
    names = ("shot_index", "purpose", "location_in", "inbound_speed_m_s", "rebound_speed_m_s", "metric", "u")
    return [
        {
            **common,
            **dict(zip(names, row[:7], strict=True)),
            "valid": row[7],
            "reasons": row[8],
            "t_utc": fired_utc[row[0]],
        }
        for row in rows
    ]


def expected_summary(run_id: str, started_utc: str, finished_utc: str) -> dict[str, Any]:
    """The `runs_summary` row of the hand-made run."""
    return {
        "run_id": run_id,
        "rig": "RIG-A",
        "bat_id": BAT,
        "procedure": "bbcor",
        "status": "finished",
        "verdict": "PASS",
        "mean": 0.455,
        "expanded_uncertainty": 0.0021,
        "k": 2.0,
        "started_utc": started_utc,
        "finished_utc": finished_utc,
    }
