"""The certificate's Instruments section: what each device said it was, and the equipment list's
calibrations, from the run's InstrumentsIdentified entries (rig.instruments)."""

from __future__ import annotations

from typing import Any

from rig.core.config import EQUIPMENT_ROLES
from rig.instruments import roles_for, uncovered
from rig.report.cert_doc import Block, Para, Table


def instrument_blocks(record: dict[str, Any]) -> list[Block]:
    """One table of the devices per session that identified them (a resumed run may have another
    instrument attached), then the equipment list with each item's calibration status."""
    sessions = record.get("instruments") or []
    if not sessions:
        return [
            Para("No instrument identities were recorded for this run (a run recorded before they were).")
        ]
    blocks: list[Block] = []
    shown: list[dict[str, Any]] = []
    for number, session in enumerate(sessions, 1):
        devices = session.get("devices") or {}
        if devices in shown:
            continue  # the same instruments as an earlier session of the run
        shown.append(devices)
        if len(sessions) > 1:
            blocks.append(Para(f"Session {number} (from {session.get('t_utc') or '?'}):"))
        blocks.append(
            Table(("device", "driver", "instrument", "serial number", "firmware", "address"), _rows(devices))
        )
    last = sessions[-1]
    equipment = last.get("equipment") or []
    if any(e.get("role") for e in equipment):  # a register with roles: which items this result used
        blocks += register_blocks(equipment, roles_for(record.get("procedure"), record.get("plan")))
    elif equipment:
        blocks.append(
            Table(
                ("equipment", "device", "serial", "certificate", "calibrated", "due", "status"),
                _items(equipment),
            )
        )
    else:
        blocks.append(Para("The rig config lists no equipment calibrations."))
    for number, session in enumerate(sessions, 1):  # every session's override, not only the last's
        override = session.get("override")
        if override:
            overdue = ", ".join(
                e.get("name", "?") for e in session.get("equipment") or [] if e.get("status") == "past due"
            )
            when = f" (session {number}, from {session.get('t_utc') or '?'})" if len(sessions) > 1 else ""
            blocks.append(
                Para(
                    f"Calibration past due ({overdue or '?'}) accepted for this run{when} by "
                    f"{override.get('who', '?')}: {override.get('why', '?')}"
                )
            )
    return blocks


def register_blocks(equipment: list[dict[str, Any]], roles: tuple[str, ...]) -> list[Block]:
    """The equipment register with each item's role and whether this result depends on it, then
    the roles it depends on that no item covers (rig.instruments.roles_for)."""
    rows = tuple(
        (name, str(e.get("role") or e.get("device") or "—"), *rest, "yes" if _role(e) in roles else "no")
        for e, (name, _, *rest) in zip(equipment, _items(equipment), strict=True)
    )
    header = ("equipment", "role", "serial", "certificate", "calibrated", "due", "status", "used")
    missing = uncovered(equipment, roles)
    if missing:
        gap = "; ".join(f"{role} ({EQUIPMENT_ROLES.get(role, '?')})" for role in missing)
        says = f"No item of the equipment register covers {len(missing)} of them: {gap}."
    else:
        says = "The equipment register covers each of them."
    used = "This result depends on the instruments of these roles: " + ", ".join(roles) + ". " + says
    return [Table(header, rows), Para(used)]


def _role(e: dict[str, Any]) -> str | None:
    role = e.get("role") or e.get("device")
    return str(role) if role else None


def _rows(devices: dict[str, Any]) -> tuple[tuple[str, ...], ...]:
    rows = []
    for kind in ("cannon", "gates", "clamp"):
        d = devices.get(kind) or {}
        said = " ".join(x for x in (d.get("maker"), d.get("model")) if x) or "did not say"
        if d.get("simulated"):
            said += " (simulated)"
        rows.append(
            (
                kind,
                str(d.get("driver", "?")),
                said,
                str(d.get("serial_number") or "—"),
                str(d.get("firmware") or "—"),
                str(d.get("address") or "—"),
            )
        )
    return tuple(rows)


def _items(equipment: list[dict[str, Any]]) -> tuple[tuple[str, ...], ...]:
    return tuple(
        (
            str(e.get("name", "?")),
            str(e.get("device") or "—"),
            str(e.get("serial") or "—"),
            str(e.get("certificate") or "—"),
            str(e.get("calibrated") or "—"),
            str(e.get("due") or "—"),
            str(e.get("status", "?")).upper() if e.get("status") == "past due" else str(e.get("status", "?")),
        )
        for e in equipment
    )
