"""`rig equipment`: the rig's equipment register, each item's calibration status, what falls due soon."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import add_columns, add_plain_row, add_rig_options, console, new_table, rig_config

DEFAULT_WITHIN_DAYS = 30


def cmd_equipment(args: argparse.Namespace) -> int:
    """rig equipment: list the rig config's equipment register (--config RIG.toml, or --sim SCENE's
    sample) with each item's role, serial, certificate, calibration date, due date and status, what
    falls due within --within DAYS (default 30), and the roles a result depends on that no item
    covers. Exit 0: all in date, nothing due within DAYS, every role covered; 1: an item past due
    or due within DAYS, or a role not covered (each listed); 2: an error.
    """
    payload = register(rig_config(args), args.within)
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        _table(payload)
    return int(payload["exit_status"])


def register(config: Any, within: int) -> dict[str, Any]:
    """The register as JSON: the items with their status and days left, and what needs doing."""
    from rig.core.config import EQUIPMENT_ROLES
    from rig.instruments import BALL_ROLES, BAT_ROLES, days_left, status, today_utc, uncovered

    day = today_utc()
    items = []
    for e in config.equipment:
        left = days_left(e, day)
        items.append(
            {
                **e.model_dump(mode="json"),
                "role": e.purpose,
                "status": status(e, day),
                "days_left": left,
                "due_within": left is not None and 0 <= left <= within,
            }
        )
    needed = tuple(dict.fromkeys((*BAT_ROLES, *BALL_ROLES)))
    missing = uncovered(items, needed)
    past = [i["name"] for i in items if i["status"] == "past due"]
    soon = [i["name"] for i in items if i["due_within"]]
    return {
        "rig": config.name,
        "day": day.isoformat(),
        "within_days": within,
        "items": items,
        "past_due": past,
        "due_within": soon,
        "uncovered_roles": [{"role": r, "what": EQUIPMENT_ROLES[r]} for r in missing],
        "exit_status": 1 if past or soon or missing else 0,
    }


def _table(payload: dict[str, Any]) -> None:
    out = console()
    table = new_table(title=f"Equipment of {payload['rig']} on {payload['day']} (UTC)")
    add_columns(table, "equipment", "role", "serial", "certificate", "calibrated", "due")
    add_columns(table, "days left", justify="right")
    add_columns(table, "status")
    for i in payload["items"]:
        status = i["status"].upper() if i["status"] == "past due" else i["status"]
        if i["due_within"]:
            status += f", due within {payload['within_days']} days"
        add_plain_row(
            table,
            i["name"],
            i["role"] or "-",
            i["serial"] or "-",
            i["certificate"] or "-",
            i["calibrated"] or "-",
            i["due"] or "-",
            "-" if i["days_left"] is None else str(i["days_left"]),
            status,
        )
    if payload["items"]:
        out.print(table)
    else:
        out.print(
            f"{payload['rig']}: the rig config lists no equipment ([[equipment]] tables)",
            markup=False,
            highlight=False,
        )
    within = payload["within_days"]
    if payload["past_due"]:
        out.print("past due: " + ", ".join(payload["past_due"]), markup=False, highlight=False)
    if payload["due_within"]:
        out.print(
            f"due within {within} days: " + ", ".join(payload["due_within"]), markup=False, highlight=False
        )
    elif not payload["past_due"]:
        out.print(f"nothing falls due within {within} days", markup=False, highlight=False)
    for gap in payload["uncovered_roles"]:
        out.print(f"no item covers the role {gap['role']}: {gap['what']}", markup=False, highlight=False)


def _days(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number of days") from None
    if not 0 <= value <= 36500:
        raise argparse.ArgumentTypeError(f"{value} must lie within 0-36500 days")
    return value


def add_parsers(sub: Any) -> None:
    """`rig equipment`."""
    p = sub.add_parser(
        "equipment", help="the equipment register and what falls due soon", description=cmd_equipment.__doc__
    )
    add_rig_options(p)
    p.add_argument(
        "--within",
        type=_days,
        default=DEFAULT_WITHIN_DAYS,
        metavar="DAYS",
        help=f"list what falls due within DAYS (default {DEFAULT_WITHIN_DAYS})",
    )
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_equipment)
