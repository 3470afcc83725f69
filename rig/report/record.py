"""A run's record as one JSON-ready document, assembled from the store's log entries."""

from __future__ import annotations

from typing import Any

from rig.core import events as ev
from rig.core.run_state import RunState, ShotEntry
from rig.report.cert_retest import RETEST_KEY
from rig.report.issue import created_meta, report_facts
from rig.store import Anchor, LogEntry, RecordRefused, Store, shown_status, status_word

SHOT_KINDS = ev.SHOT_KINDS
RUN_LOCK_BROKEN = "RunLockBroken"  # the store's entry for a broken run lock (not a run event)


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
        "status": _status(store, summary, entries, coverage["by"], closing),
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
    st = RunState()
    for e in entries:
        if e.kind in ev.BY_KIND:
            st.apply(ev.parse_entry(e), e.t_utc, e.seq)
    _fill(record, st, [e for e in entries if e.kind == RUN_LOCK_BROKEN])
    created = created_meta(entries)
    if created.get("check_ack"):  # made under an acknowledged signal
        record["check_ack"] = created["check_ack"]
    if RETEST_KEY in created:  # a retest: the bat's earlier result
        record[RETEST_KEY] = created[RETEST_KEY]
    record.update(report_facts(store, run_id, entries))  # none for a run recorded before them
    return record


def _status(store: Store, summary: Any, entries: list[LogEntry], by: str, closing: list[LogEntry]) -> str:
    """The run's status as every output shows it (rig.store.shown_status), as far as the record goes:
    cut at an anchor, the run was open there and interrupted only if that entry says so."""
    if closing:
        return status_word(str(closing[-1].payload.get("status")))
    if by == "anchor":
        return status_word("running", entries[-1].kind if entries else None, runner_alive=True)
    return shown_status(store, summary)


def _fill(record: dict[str, Any], st: RunState, locks: list[LogEntry]) -> None:
    """The record's sections from the run's fold (and the broken locks the store recorded)."""
    if st.setup is not None:
        for key in ("procedure", "bat", "rig", "software"):
            record[key] = st.setup.get(key)
        if "ball" in st.setup:  # the ball terms (lot, source, sensitivities, law); none in older runs
            record["ball"] = st.setup["ball"]
        if st.setup.get("plan"):  # a lab's own plan (rig.plans) ran the procedure, not the standard one
            record["plan"] = st.setup["plan"]
    record["environment"] = [{**n.data, "t_utc": n.t_utc} for n in st.environment_checks]
    record["moi"] = None if st.moi is None else st.moi.to_payload()
    if st.instruments:  # runs recorded before instruments were identified have none
        record["instruments"] = [{**n.data, "t_utc": n.t_utc} for n in st.instruments]
    record["operator"] = [{"kind": n.kind, **n.data, "t_utc": n.t_utc} for n in st.operator]
    record["location"] = None if st.location is None else st.location.data
    stops = [(n.seq or 0, {"kind": n.kind, **n.data, "t_utc": n.t_utc}) for n in st.stops]
    for e in locks:  # a killed runner's lock, broken by the next one
        holder = e.payload.get("holder") or {}
        why = f"lock of host {holder.get('host')} pid {holder.get('pid')} broken: {e.payload.get('reason')}"
        stops.append((e.seq, {"kind": e.kind, "reason": why, "t_utc": e.t_utc}))
    record["interruptions"] = [stop for _, stop in sorted(stops, key=lambda s: s[0])]
    record["rig_checks"] = [{**n.data, "t_utc": n.t_utc} for n in st.stops if n.kind == ev.RIG_CHECKED]
    ended = [n for n in st.stops if n.kind == ev.RUN_ENDED]
    record["ended"] = {**ended[-1].data, "t_utc": ended[-1].t_utc} if ended else None
    record["scan_extensions"] = [{**n.data, "t_utc": n.t_utc} for n in st.scan_extensions]
    if st.verdict is not None:
        record["verdict"] = {k: v for k, v in st.verdict.to_payload().items() if k != "cross_check"}
        record["cross_check"] = st.verdict.cross_check
    record["shots"] = [_shot(st.by_index[i]) for i in sorted(st.by_index)]
    if st.abi:  # an accelerated break-in's compressions, rollings, stages and inspections, in order
        record["abi"] = [{"kind": n.kind, **n.data, "t_utc": n.t_utc} for n in st.abi]


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


_RAW_KEYS = (
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
_BALL_KEYS = ("ball", "ball_hits")  # the ball's id and its hits before this shot, where recorded
_AIR_KEYS = ("temperature_c", "humidity_pct")  # the lab's air at the shot, where the run read it


def _shot(s: ShotEntry) -> dict[str, Any]:
    """One shot of the record: its request, raw data (ticks first), outcome and reasons."""
    shot: dict[str, Any] = {"index": s.index, "status": s.status}
    if s.requested is not None:
        r = s.requested
        shot.update(
            purpose=r.purpose,
            location_in=r.location_in,
            requested_utc=s.requested_utc,
            target_speed_m_s=r.target_speed_m_s,
        )
        shot.update({k: v for k in _AIR_KEYS if (v := getattr(r, k)) is not None})
    if s.raw is not None:
        raw = s.raw.data  # the raw record as written
        shot["raw"] = {k: raw.get(k) for k in _RAW_KEYS} | {k: raw[k] for k in _BALL_KEYS if k in raw}
    if s.outcome is not None:
        o = s.outcome
        shot.update(
            valid=o.valid,
            inbound_speed_m_s=o.inbound_speed_m_s,
            rebound_speed_m_s=o.rebound_speed_m_s,
            inbound_at_impact_m_s=o.inbound_at_impact_m_s,  # drag-corrected (none in old runs)
            rebound_at_impact_m_s=o.rebound_at_impact_m_s,
            metrics=o.metrics,
            metric=o.metric,
            u=o.u,
            reasons=list(o.reasons),
            budget=o.budget,
        )
        shot.update(o.shown())  # fields a lab added to the outcome, declared shown (rig.core.outcomes)
    for over in s.overruled:
        shot["valid"] = False
        shot.setdefault("reasons", []).append(
            {
                "code": "OPERATOR_REJECTED",
                "message": f"{over.reason or ''} ({over.who or ''})",
                "invalidates": True,
            }
        )
    if s.lost:
        shot.update(valid=False, reasons=[{"code": "LOST", "message": s.lost_reason or ""}])
    return shot
