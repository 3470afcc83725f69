"""A run's test report as the lab issues it: its report id, its issue (an act, recorded), and what a
new run recorded for it when it was created (the lab, who performed the test, whether simulated).

Issuing is a lab-level 'ReportIssued' entry {run_id, report_id, issued (date), by}, appended like a
run's signature: the run itself is sealed, and nothing in a report depends on the time it is
rendered, so a report shows its issue only once this entry exists (DRAFT - NOT ISSUED before).
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from rig.core.errors import ConfigError, RecordRefused
from rig.store import RUN_CREATED, LogEntry, Store, run_seal

REPORT_ISSUED = "ReportIssued"  # lab-level: {run_id, report_id, issued, by}
SIMULATED_MARK = "SIMULATED - NOT A CERTIFICATION"
DRAFT_MARK = "DRAFT - NOT ISSUED"


def default_report_id(run_id: str) -> str:
    """The report id of a run: 'R-' and the first 12 hex digits of its run id (as `rig runs` shows it)."""
    return f"R-{run_id[:12]}"


def issues(store: Store, run_id: str) -> list[dict[str, Any]]:
    """The run's issue entries, oldest first: {report_id, issued, by, seq, t_utc}."""
    return [
        {**{k: e.payload.get(k) for k in ("report_id", "issued", "by")}, "seq": e.seq, "t_utc": e.t_utc}
        for e in store.entries(None, kinds=[REPORT_ISSUED])
        if e.payload.get("run_id") == run_id
    ]


def created_meta(entries: list[LogEntry]) -> dict[str, Any]:
    """What the run's creation recorded beside the run (RunCreated's meta; {} if none)."""
    created = next((e for e in entries if e.kind == RUN_CREATED), None)
    meta = created.payload.get("meta") if created is not None else None
    return meta if isinstance(meta, dict) else {}


def report_facts(store: Store, run_id: str, entries: list[LogEntry]) -> dict[str, Any]:
    """The record's report keys: for a run created with them (RunCreated's meta 'report'), the lab,
    who tested, whether simulated, the report id and the seal; for any issued run, its issue.
    A run recorded before them gets none (its JSON record stays as it was)."""
    report = created_meta(entries).get("report")
    facts: dict[str, Any] = {}
    if isinstance(report, dict):
        simulated = bool(report.get("simulated"))
        facts = {
            "simulated": simulated,
            **({"simulated_notice": SIMULATED_MARK} if simulated else {}),
            "report_id": default_report_id(run_id),
            "lab": report.get("lab"),
            "tested_by": {"name": report.get("tested_by"), "answered_by": report.get("answered_by")},
            "seal": run_seal(store, run_id),
        }
    issued = issues(store, run_id)
    if issued or facts:
        facts["issue"] = issued[0] if issued else None
    return facts


def _name(by: str) -> str:
    if not isinstance(by, str) or not by.strip() or len(by) > 200 or not by.isprintable():
        raise ConfigError("who authorises the report: 1-200 printable characters", source="--by")
    return by.strip()


def issue(store: Store, run_id: str, by: str) -> dict[str, Any]:
    """Issue the run's report, authorised by `by`, dated today (UTC): a ReportIssued entry. Refused
    for a run that is not sealed, or whose report was issued already."""
    who = _name(by)
    run = store.run(run_id)
    if run.status == "running":
        raise RecordRefused(f"run {run_id} is not sealed: its report is issued once it is finished or ended")
    done = issues(store, run_id)
    if done:
        first = done[0]
        raise RecordRefused(
            f"the report of run {run_id} was issued already: {first['report_id']} on {first['issued']} "
            f"by {first['by']}"
        )
    report_id = default_report_id(run_id)
    taken = {e.payload.get("report_id") for e in store.entries(None, kinds=[REPORT_ISSUED])}
    if report_id in taken:  # another run's id starts with the same 12 digits: the whole id, unique
        report_id = f"R-{run_id}"
    payload = {
        "run_id": run_id,
        "report_id": report_id,
        "issued": datetime.now(UTC).date().isoformat(),
        "by": who,
    }
    entry = store.append(None, REPORT_ISSUED, payload)
    return {**{k: payload[k] for k in ("report_id", "issued", "by")}, "seq": entry.seq, "t_utc": entry.t_utc}
