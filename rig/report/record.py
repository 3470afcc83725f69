"""A run's record as one JSON-ready document, assembled from the store's log entries."""

from __future__ import annotations

from typing import Any

from rig.store import Store

SHOT_KINDS = ("ShotRequested", "ShotFired", "ShotMeasured", "ShotRejected", "ShotLost", "ShotOverruled")


def run_record(store: Store, run_id: str) -> dict[str, Any]:
    """Everything about one run: set-up, every shot (raw ticks first), the verdict, the anchors."""
    summary = store.run(run_id)
    entries = store.entries(run_id)
    record: dict[str, Any] = {
        "run_id": run_id,
        "status": summary.status,
        "procedure": None,
        "bat": None,
        "rig": None,
        "software": None,
        "environment": [],
        "moi": None,
        "shots": [],
        "location": None,
        "operator": [],
        "interruptions": [],
        "rig_checks": [],
        "ended": None,
        "scan_extensions": [],
        "verdict": None,
        "cross_check": None,
        "started_utc": summary.started_utc,
        "entries": len(entries),
        "anchor": {"seq": entries[-1].seq if entries else 0, "hash": entries[-1].hash if entries else ""},
    }
    shots: dict[int, dict[str, Any]] = {}
    for e in entries:
        d = e.payload
        if e.kind == "RunStarted":
            for key in ("procedure", "bat", "rig", "software"):
                record[key] = d.get(key)
        elif e.kind == "EnvironmentChecked":
            record["environment"].append({**d, "t_utc": e.t_utc})
        elif e.kind == "MoiMeasured":
            record["moi"] = d
        elif e.kind in ("OperatorPrompted", "OperatorAnswered"):
            record["operator"].append({"kind": e.kind, **d, "t_utc": e.t_utc})
        elif e.kind == "LocationChosen":
            record["location"] = d
        elif e.kind in ("RunInterrupted", "RunResumed", "RigChecked", "RunEnded"):
            record["interruptions"].append({"kind": e.kind, **d, "t_utc": e.t_utc})
            if e.kind == "RigChecked":
                record["rig_checks"].append({**d, "t_utc": e.t_utc})
            elif e.kind == "RunEnded":
                record["ended"] = {**d, "t_utc": e.t_utc}
        elif e.kind == "ScanExtended":
            record["scan_extensions"].append({**d, "t_utc": e.t_utc})
        elif e.kind == "RunFinished":
            record["verdict"] = {k: v for k, v in d.items() if k != "cross_check"}
            record["cross_check"] = d.get("cross_check")
        elif e.kind in SHOT_KINDS:
            shot = shots.setdefault(d["index"], {"index": d["index"], "status": "requested"})
            _merge_shot(shot, e.kind, d, e.t_utc)
    record["shots"] = [shots[i] for i in sorted(shots)]
    return record


def _merge_shot(shot: dict[str, Any], kind: str, d: dict[str, Any], t_utc: str) -> None:
    if kind == "ShotRequested":
        shot.update(
            purpose=d["purpose"],
            location_in=d["location_in"],
            requested_utc=t_utc,
            target_speed_m_s=d.get("target_speed_m_s"),
        )
    elif kind == "ShotFired":
        shot.update(
            status="fired",
            raw={
                k: d.get(k)
                for k in (
                    "shot_number",
                    "pressure_kpa",
                    "impact_from_pivot_m",
                    "gate_positions_m",
                    "gate_config",
                    "crossings",
                    "recoil_rad_s",
                    "notes",
                    "ball_number",
                )
            },
        )
    elif kind in ("ShotMeasured", "ShotRejected"):
        shot.update(
            status="valid" if kind == "ShotMeasured" else "invalid",
            valid=kind == "ShotMeasured",
            inbound_speed_m_s=d.get("inbound_speed_m_s"),
            rebound_speed_m_s=d.get("rebound_speed_m_s"),
            metrics=d.get("metrics"),
            metric=d.get("metric"),
            u=d.get("u"),
            reasons=d.get("reasons", []),
            budget=d.get("budget"),
        )
    elif kind == "ShotOverruled":
        shot.update(status="invalid", valid=False)
        shot.setdefault("reasons", []).append(
            {
                "code": "OPERATOR_REJECTED",
                "message": f"{d.get('reason', '')} ({d.get('who', '')})",
                "invalidates": True,
            }
        )
    elif kind == "ShotLost":
        shot.update(status="lost", valid=False, reasons=[{"code": "LOST", "message": d.get("reason", "")}])
