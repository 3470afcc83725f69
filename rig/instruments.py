"""The instruments of a run: what each device says it is, its equipment-list entry, its calibration.

Read when a run's devices open (a new run before it is created, a resumed run again) and recorded
as InstrumentsIdentified, so the certificate lists the instruments used. An instrument past its
calibration due date stops the run unless an override (who, why) is recorded with it; a device
whose serial number differs from its equipment-list entry stops it always (the wrong instrument
is attached, or the list is wrong).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, date, datetime
from typing import Any

from rig.core import events as ev
from rig.core.config import DEVICE_KINDS, OPTIONAL_KINDS, Equipment, RigConfig
from rig.core.devices import Identifiable, InstrumentIdentity
from rig.core.errors import ConfigError, DeviceError


@dataclass(frozen=True)
class Identified:
    """The event to record, and what stops the run (empty: it may go on)."""

    event: ev.InstrumentsIdentified
    refusals: tuple[str, ...]


def today_utc() -> date:
    """The calibration dates are compared with today's date in UTC."""
    return datetime.now(UTC).date()


def identify(
    session: Any, config: RigConfig, override: dict[str, str] | None, today: date | None = None
) -> Identified:
    """Ask each device of the open `session` what it is and check the equipment list; `override`
    ({who, why}) accepts calibrations past due, and is recorded with them."""
    day = today or today_utc()
    devices: dict[str, Any] = {}
    refusals: list[str] = []
    present = [k for k in OPTIONAL_KINDS if getattr(session, k, None) is not None]  # a compression tester
    for kind in (*DEVICE_KINDS, *present):
        spec = config.device(kind)
        said = _identity(kind, getattr(session, kind))
        devices[kind] = {
            "driver": spec.driver,
            "address": spec.address,
            "simulated": spec.is_simulated,
            **({} if said is None else _fields(said)),
        }
        for item in (e for e in config.equipment if e.device == kind and e.serial):
            reported = _serials(said)
            if not reported:
                refusals.append(
                    f"the equipment list gives {item.name!r} serial number {item.serial}, but the {kind} "
                    "device reports none: its identity cannot be checked"
                )
            elif item.serial not in reported:
                refusals.append(
                    f"the {kind} device reports serial number {said.serial_number if said else '?'}, but the "
                    f"equipment list's {item.name!r} says {item.serial}: attach the listed instrument or "
                    "correct the list"
                )
    overdue = [e for e in config.equipment if e.due is not None and e.due < day]
    if overdue and override is None:
        names = ", ".join(f"{e.name} (due {e.due})" for e in overdue)
        refusals.append(
            f"calibration past due: {names}; recalibrate, or accept it for this run with "
            "--accept-overdue --who NAME --why TEXT (recorded)"
        )
    equipment = [
        {**e.model_dump(mode="json", exclude_none=True), "status": status(e, day)} for e in config.equipment
    ]
    accepted = override if overdue else None
    event = ev.InstrumentsIdentified(devices=devices, equipment=equipment, override=accepted)
    return Identified(event, tuple(refusals))


def status(item: Equipment, day: date) -> str:
    """'in date', 'past due' or 'no due date' on `day`."""
    if item.due is None:
        return "no due date"
    return "past due" if item.due < day else "in date"


# The roles a result depends on, by what the run does [assumed: read from what each procedure's
# result is computed from; a lab's own procedure that measures less may need fewer].
DEVICE_ROLES = ("cannon", "gates", "clamp")
AIR_ROLES = ("thermometer", "hygrometer", "barometer")  # the conditions window and the drag correction
BAT_ROLES = (*DEVICE_ROLES, "gate-gauge", "pendulum-timer", "scale", *AIR_ROLES)  # speeds, MOI, mass
BALL_ROLES = (*DEVICE_ROLES, "gate-gauge", "scale", *AIR_ROLES, "compression-tester")  # a lot's test
SHOT_ROLES = ("cannon", "gates", "gate-gauge")  # one shot's speeds


ABI_ROLES = (*BAT_ROLES, "barrel-compression-tester")  # an accelerated break-in: its stages' BC too


def roles_for(procedure: Mapping[str, Any] | None, plan: str | None = None) -> tuple[str, ...]:
    """The equipment roles the result of a run of `procedure` (as a record holds it; `plan`: the
    plan it recorded) depends on: an accelerated break-in's, a bat certification's (a `standard`),
    a ball test's (a `test`), else one shot's."""
    procedure = procedure or {}
    if procedure.get("standard"):
        return ABI_ROLES if plan == ev.ABI_PLAN else BAT_ROLES
    if procedure.get("test"):
        return BALL_ROLES
    return SHOT_ROLES


def uncovered(equipment: Iterable[Mapping[str, Any]], roles: Iterable[str]) -> list[str]:
    """The `roles` no item of `equipment` (items as recorded: role, else device) covers."""
    covered = {e.get("role") or e.get("device") for e in equipment}
    return [role for role in roles if role not in covered]


def days_left(item: Equipment, day: date) -> int | None:
    """Days from `day` to the item's due date (negative: past due); None without one."""
    return None if item.due is None else (item.due - day).days


def _identity(kind: str, device: object) -> InstrumentIdentity | None:
    """What the device says it is; None if its driver cannot say. A device that does not answer
    stops the run before anything moves (ConfigError naming it)."""
    if not isinstance(device, Identifiable):
        return None
    try:
        said = device.identify()
    except DeviceError as exc:
        raise ConfigError(f"the {kind} did not say what it is: {exc}", source="instruments") from None
    return said if isinstance(said, InstrumentIdentity) else None


def _serials(said: InstrumentIdentity | None) -> set[str]:
    """The serial numbers a device reports: one, or one per part ("stage / sensor")."""
    if said is None or not said.serial_number.strip():
        return set()
    return {part.strip() for part in said.serial_number.split(" / ") if part.strip()}


def _fields(said: InstrumentIdentity) -> dict[str, str]:
    return {
        "maker": said.maker,
        "model": said.model,
        "serial_number": said.serial_number,
        "firmware": said.firmware,
    }
