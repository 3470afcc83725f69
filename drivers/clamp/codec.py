"""Pivot-clamp wire codec (see docs/devices/clamp.md).

The clamp grips the bat's handle on a pivot 6 in from the knob. A stage sets the impact point's
distance from the pivot; an encoder on the pivot reports the bat's recoil after each impact and
the pendulum period used to measure the MOI (ASTM F2398).
"""

from __future__ import annotations

from rig.core.devices import STAGE_RANGE_MM, ClampStatus, PendulumPeriod, Recoil
from rig.drivers.codec import CommandSpec, flag, integer, number
from rig.drivers.wire import Event, Reply

STAGE_MIN_MM, STAGE_MAX_MM = STAGE_RANGE_MM


SPECS = {
    s.verb: s
    for s in (
        CommandSpec("ID", (), "identify: MODEL=, FW=, SN="),
        CommandSpec("STATUS", (), "LOCK=, POS= (mm), MOVING=, DEG="),
        CommandSpec("CLAMP", (), "grip the bat; ! LOCK L=1 when the sensor confirms"),
        CommandSpec("RELEASE", (), "open the grip; ! LOCK L=0"),
        CommandSpec("MOVE", (number(STAGE_MIN_MM, STAGE_MAX_MM),), "impact point from the pivot, mm"),
        CommandSpec("SWING", (integer(1, 100),), "time n pendulum cycles; ! PERIOD US= AMP= N="),
    )
}


def parse_status(reply: Reply) -> ClampStatus:
    """Typed view of a STATUS reply."""
    fields = reply.named()
    try:
        return ClampStatus(
            flag(fields["LOCK"]), float(fields["POS"]), flag(fields["MOVING"]), float(fields["DEG"])
        )
    except KeyError as exc:
        raise ValueError(f"STATUS reply lacks field {exc.args[0]}") from None


def parse_period(event: Event) -> PendulumPeriod:
    """Typed view of a PERIOD event."""
    fields = event.named()
    try:
        period = PendulumPeriod(float(fields["US"]) * 1e-6, float(fields["AMP"]), int(fields["N"]))
    except KeyError as exc:
        raise ValueError(f"PERIOD event lacks field {exc.args[0]}") from None
    if not period.period_s > 0:
        raise ValueError(f"non-positive pendulum period {period.period_s}")
    return period


def parse_recoil(event: Event) -> Recoil:
    """Typed view of a RECOIL event."""
    fields = event.named()
    try:
        return Recoil(float(fields["W"]))
    except KeyError as exc:
        raise ValueError(f"RECOIL event lacks field {exc.args[0]}") from None
