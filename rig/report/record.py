"""A run's record as one JSON-ready document, assembled from the store's log entries."""

from __future__ import annotations

from typing import Any

from rig.core import events as ev
from rig.store import Anchor, LogEntry, RecordRefused, Store

SHOT_KINDS = ev.SHOT_KINDS


_CLOSED = ("finished", "aborted")


def run_record(store: Store, run_id: str, anchor: Anchor | None = None) -> dict[str, Any]:
    """Everything about one run: set-up, every shot (raw ticks first), the verdict, the anchors.

    Only what the run's seal (its closing status entry) and `anchor` cover is shown: anything
    of the run after them is left out, and `coverage` says so.
    """
    summary = store.run(run_id)
    entries, coverage = covered(store, run_id, anchor)
    closing = [e for e in entries if e.kind == "RunStatusChanged"]
    record: dict[str, Any] = {
        "run_id": run_id,
        "status": closing[-1].payload.get("status") if closing else "running",
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
        "coverage": coverage,
    }
    shots: dict[int, dict[str, Any]] = {}
    for e in entries:
        d = e.payload
        if e.kind == ev.RUN_STARTED:
            for key in ("procedure", "bat", "rig", "software"):
                record[key] = d.get(key)
        elif e.kind == ev.ENVIRONMENT_CHECKED:
            record["environment"].append({**d, "t_utc": e.t_utc})
        elif e.kind == ev.MOI_MEASURED:
            record["moi"] = d
        elif e.kind in (ev.OPERATOR_PROMPTED, ev.OPERATOR_ANSWERED):
            record["operator"].append({"kind": e.kind, **d, "t_utc": e.t_utc})
        elif e.kind == ev.LOCATION_CHOSEN:
            record["location"] = d
        elif e.kind in (ev.RUN_INTERRUPTED, ev.RUN_RESUMED, ev.RIG_CHECKED, ev.RUN_ENDED):
            record["interruptions"].append({"kind": e.kind, **d, "t_utc": e.t_utc})
            if e.kind == ev.RIG_CHECKED:
                record["rig_checks"].append({**d, "t_utc": e.t_utc})
            elif e.kind == ev.RUN_ENDED:
                record["ended"] = {**d, "t_utc": e.t_utc}
        elif e.kind == "RunLockBroken":  # a killed runner's lock, broken by the next one
            holder = d.get("holder") or {}
            why = f"lock of host {holder.get('host')} pid {holder.get('pid')} broken: {d.get('reason')}"
            record["interruptions"].append({"kind": e.kind, "reason": why, "t_utc": e.t_utc})
        elif e.kind == ev.SCAN_EXTENDED:
            record["scan_extensions"].append({**d, "t_utc": e.t_utc})
        elif e.kind == ev.RUN_FINISHED:
            record["verdict"] = {k: v for k, v in d.items() if k != "cross_check"}
            record["cross_check"] = d.get("cross_check")
        elif e.kind in SHOT_KINDS:
            shot = shots.setdefault(d["index"], {"index": d["index"], "status": "requested"})
            _merge_shot(shot, e.kind, d, e.t_utc)
    record["shots"] = [shots[i] for i in sorted(shots)]
    return record


def covered(store: Store, run_id: str, anchor: Anchor | None = None) -> tuple[list[LogEntry], dict[str, Any]]:
    """The run's entries up to its seal (and up to `anchor`), and what was left out and why."""
    entries = store.entries(run_id)
    seal = next(
        (e for e in entries if e.kind == "RunStatusChanged" and e.payload.get("status") in _CLOSED), None
    )
    limit, by = (seal.seq, "seal") if seal else (None, "head")
    if anchor is not None:
        at = store.entry(anchor.seq)
        if at is None or at.hash != anchor.hash:
            found = "no such entry" if at is None else f"the store has hash {at.hash}"
            raise RecordRefused(
                f"anchor {anchor}: {found}; the record was cut or rewritten after this anchor was "
                "printed (rig verify --anchor says more)"
            )
        if limit is None or anchor.seq < limit:
            limit, by = anchor.seq, "anchor"
    kept = [e for e in entries if limit is None or e.seq <= limit]
    left = [
        {"seq": e.seq, "kind": e.kind, "t_utc": e.t_utc}
        for e in entries
        if limit is not None and e.seq > limit
    ]
    return kept, {
        "by": by,
        "upto_seq": kept[-1].seq if kept else 0,
        "left_out": left,
        "text": _coverage_text(by, kept, left),
    }


def _coverage_text(by: str, kept: list[LogEntry], left: list[dict[str, Any]]) -> str:
    last = kept[-1].seq if kept else 0
    text = {
        "seal": f"This record covers the run up to its seal, entry {last}: the run was closed there.",
        "anchor": f"This record covers the run up to the anchor, entry {last}.",
        "head": f"This record covers the run up to entry {last}; the run is still open.",
    }[by]
    if left and by == "seal":
        kinds = ", ".join(sorted({e["kind"] for e in left}))
        text += (
            f" {len(left)} later entries of this run ({kinds}, from entry {left[0]['seq']}) were written "
            "after the seal, which the store refuses: they are not part of this record "
            "(rig verify reports them)."
        )
    elif left:
        text += f" {len(left)} later entries of this run (from entry {left[0]['seq']}) are not shown."
    return text


def _merge_shot(shot: dict[str, Any], kind: str, d: dict[str, Any], t_utc: str) -> None:
    if kind == ev.SHOT_REQUESTED:
        shot.update(
            purpose=d["purpose"],
            location_in=d["location_in"],
            requested_utc=t_utc,
            target_speed_m_s=d.get("target_speed_m_s"),
        )
    elif kind == ev.SHOT_FIRED:
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
    elif kind in (ev.SHOT_MEASURED, ev.SHOT_REJECTED):
        shot.update(
            status="valid" if kind == ev.SHOT_MEASURED else "invalid",
            valid=kind == ev.SHOT_MEASURED,
            inbound_speed_m_s=d.get("inbound_speed_m_s"),
            rebound_speed_m_s=d.get("rebound_speed_m_s"),
            inbound_at_impact_m_s=d.get("inbound_at_impact_m_s"),  # drag-corrected (none in old runs)
            rebound_at_impact_m_s=d.get("rebound_at_impact_m_s"),
            metrics=d.get("metrics"),
            metric=d.get("metric"),
            u=d.get("u"),
            reasons=d.get("reasons", []),
            budget=d.get("budget"),
        )
    elif kind == ev.SHOT_OVERRULED:
        shot.update(status="invalid", valid=False)
        shot.setdefault("reasons", []).append(
            {
                "code": "OPERATOR_REJECTED",
                "message": f"{d.get('reason', '')} ({d.get('who', '')})",
                "invalidates": True,
            }
        )
    elif kind == ev.SHOT_LOST:
        shot.update(status="lost", valid=False, reasons=[{"code": "LOST", "message": d.get("reason", "")}])
