"""A run record (rig.report.record.run_record) as a short Markdown summary for the history screen."""

from __future__ import annotations

from typing import Any


def _num(x: Any, fmt: str = ".4f") -> str:
    return "-" if x is None else format(x, fmt)


def record_summary(record: dict[str, Any]) -> str:
    """The verdict, the set-up, and one table row per shot."""
    p, bat, v = record.get("procedure") or {}, record.get("bat") or {}, record.get("verdict")
    lines = [f"# Run {record['run_id'][:8]}: {record['status']}", ""]
    if v and "mean" in v:
        lines.append(
            f"**{v['verdict']}** ({v.get('zone', '')}): {v['metric']} = {v['mean']:.4f}, "
            f"U = {v['U']:.4f} (k = {v['coverage_k']:g}), limit {v['limit']:g}; {v.get('decision_rule', '')}"
        )
    elif v:
        lines.append(f"**{v['verdict']}**: {v.get('reason', '')}")
    else:
        last = (record.get("interruptions") or [{}])[-1]
        lines.append(f"**No verdict**: {last.get('reason', 'the run has not finished')}")
    cc = record.get("cross_check") or {}
    if cc.get("predicted") is not None:
        lines.append(
            f"\nModel at {cc.get('hoop_hz') or 'rigid'} Hz predicts {cc['predicted']:.4f}: {cc['note']}"
        )
    lines += ["", "## Set-up", ""]
    if p:
        lines.append(f"- procedure: {p.get('name')} ({p.get('edition')})")
    if bat:
        size = f"{bat.get('length_in')} in, {bat.get('weight_oz')} oz"
        lines.append(
            f"- bat {bat.get('id')}: {size}, {bat.get('barrel')}, hoop {bat.get('hoop_hz') or '-'} Hz"
        )
    if record.get("moi"):
        lines.append(f"- MOI {record['moi']['moi_kgm2']:.5f} kg m² ({record['moi']['source']})")
    if record.get("location"):
        lines.append(f"- location of maximum performance: {record['location']['from_barrel_end_in']:g} in")
    lines.append(f"- records: {record['entries']} entries; `rig verify` checks their chain")
    return "\n".join(lines + _shots(record)) + "\n"


def one_shot_summary(record: dict[str, Any]) -> str:
    """A one-shot run (rig shot): what was asked and its shot; it is no certification."""
    asked = record.get("procedure") or {}
    lines = [f"# Run {record['run_id'][:8]}: one shot ({record['status']})", ""]
    lines.append("**Not a certification**: one shot fired by `rig shot`, no verdict.")
    lines += ["", "## Set-up", ""]
    speed, at = _num(asked.get("speed_m_s"), "g"), _num(asked.get("impact_from_pivot_m"), "g")
    lines.append(f"- asked: {speed} m/s, the stage at {at} m from the pivot")
    lines.append(f"- records: {record['entries']} entries; `rig verify` checks their chain")
    return "\n".join(lines + _shots(record)) + "\n"


def _shots(record: dict[str, Any]) -> list[str]:
    """The shots table: one row per shot."""
    lines = ["", "## Shots", "", "| # | purpose | at (in) | in (m/s) | out (m/s) | metric | u | status |"]
    lines.append("|---|---|---|---|---|---|---|---|")
    for s in record.get("shots", []):
        why = "; ".join(r.get("code", "") for r in s.get("reasons", []) if r.get("invalidates", True))
        status = s.get("status", "") + (f" ({why})" if why and s.get("status") != "valid" else "")
        lines.append(
            f"| {s['index']} | {s.get('purpose', '')} | {_num(s.get('location_in'), 'g')} "
            f"| {_num(s.get('inbound_speed_m_s'), '.2f')} | {_num(s.get('rebound_speed_m_s'), '.2f')} "
            f"| {_num(s.get('metric'))} | {_num(s.get('u'))} | {status} |"
        )
    return lines
