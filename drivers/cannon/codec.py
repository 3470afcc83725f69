"""Air-cannon wire codec and its state table (see docs/devices/cannon.md).

The state table lives here, once: the driver consults it to refuse an illegal command before
sending it, and the simulator treats it as authoritative.
"""

from __future__ import annotations

from rig.core.devices import CannonState, CannonStatus, Environment, Interlocks
from rig.drivers.codec import CommandSpec, flag, number, token
from rig.drivers.wire import Event, Reply

MAX_PRESSURE_KPA = 1000.0
BALL_ID_MAX = 40  # characters of a ball id (lot id, '-', ball number)
READY_BAND = 0.01  # pressure within 1 % of the setpoint counts as ready to arm

_S, _A, _F, _X = CannonState.SAFE, CannonState.ARMED, CannonState.FIRED, CannonState.FAULT
# The state table: command -> {state it is accepted in: the state it leads to}. Commands not listed
# (ID, STATUS, ENV) are accepted in every state and change nothing. The device also moves on its
# own: FIRED -> SAFE when the valve closes, ARMED -> SAFE when an interlock opens, -> FAULT on a fault.
STATE_TABLE: dict[str, dict[CannonState, CannonState]] = {
    "PSET": {_S: _S},
    "LOAD": {_S: _S},
    "ARM": {_S: _A},
    "FIRE": {_A: _F},
    "VENT": {_S: _S, _A: _S, _F: _S, _X: _X},
    "RESET": {_X: _S},
}


def refuse_in_state(verb: str, state: CannonState) -> str | None:
    """Why the state table refuses `verb` in `state`, or None if it accepts it."""
    accepted = STATE_TABLE.get(verb)
    if accepted is None or state in accepted:
        return None
    return f"cannon is {state}, not {' or '.join(accepted)}"


def next_state(verb: str, state: CannonState) -> CannonState:
    """The state right after `verb` is accepted in `state`."""
    return STATE_TABLE.get(verb, {}).get(state, state)


def state_limited(verb: str) -> bool:
    """True if some state refuses `verb` (a host must then check the state before sending it)."""
    return verb in STATE_TABLE and len(STATE_TABLE[verb]) < len(CannonState)


def status_ready(status: CannonStatus) -> bool:
    """Pressure has reached the setpoint."""
    return pressure_ready(status.pressure_kpa, status.setpoint_kpa)


def interlock_fields(ilk: Interlocks) -> dict[str, bool]:
    """Wire fields DOOR, CLAMP, ESTOP."""
    return {"DOOR": ilk.door, "CLAMP": ilk.clamp, "ESTOP": ilk.estop}


def parse_interlocks(named: dict[str, str]) -> Interlocks:
    """Parse DOOR=, CLAMP=, ESTOP= fields."""
    try:
        return Interlocks(flag(named["DOOR"]), flag(named["CLAMP"]), flag(named["ESTOP"]))
    except KeyError as exc:
        raise ValueError(f"interlock field {exc.args[0]} missing") from None


def pressure_ready(pressure_kpa: float, setpoint_kpa: float) -> bool:
    """Within the ready band of a positive setpoint."""
    return setpoint_kpa > 0 and abs(pressure_kpa - setpoint_kpa) <= READY_BAND * setpoint_kpa


def refuse_arm(status: CannonStatus) -> str | None:
    """Why ARM must be refused in this status, or None if it may proceed."""
    if (reason := refuse_in_state("ARM", status.state)) is not None:
        return reason
    if not status.interlocks.all_closed:
        return "interlock open: " + ", ".join(status.interlocks.open_names())
    if not status_ready(status):
        return f"pressure {status.pressure_kpa:.1f} kPa not at setpoint {status.setpoint_kpa:.1f} kPa"
    return None


def refuse_fire(status: CannonStatus) -> str | None:
    """Why FIRE must be refused in this status, or None if it may proceed."""
    if (reason := refuse_in_state("FIRE", status.state)) is not None:
        return reason
    if not status.interlocks.all_closed:
        return "interlock open: " + ", ".join(status.interlocks.open_names())
    return None


SPECS = {
    s.verb: s
    for s in (
        CommandSpec("ID", (), "identify: MODEL=, FW=, SN="),
        CommandSpec("STATUS", (), "STATE=, P=, SET= (kPa), DOOR=, CLAMP=, ESTOP=, SHOTS="),
        CommandSpec(
            "PSET", (number(0.0, MAX_PRESSURE_KPA),), "set the tank pressure setpoint, kPa (SAFE only)"
        ),
        CommandSpec("LOAD", (token(BALL_ID_MAX),), "the ball now in the breech, by its id (SAFE only)"),
        CommandSpec("ARM", (), "SAFE -> ARMED; needs every interlock closed and the pressure ready"),
        CommandSpec("FIRE", (), "ARMED -> FIRED; needs every interlock closed"),
        CommandSpec("VENT", (), "dump the tank and return to SAFE"),
        CommandSpec("RESET", (), "FAULT -> SAFE (tank vented)"),
        CommandSpec("ENV", (), "lab sensors: TEMP_C=, RH= (percent)"),
    )
}


def parse_status(reply: Reply) -> CannonStatus:
    """Typed view of a STATUS reply; raises ValueError naming a missing or bad field."""
    named = reply.named()
    try:
        return CannonStatus(
            state=CannonState(named["STATE"]),
            pressure_kpa=float(named["P"]),
            setpoint_kpa=float(named["SET"]),
            interlocks=parse_interlocks(named),
            shots=int(named["SHOTS"]),
        )
    except KeyError as exc:
        raise ValueError(f"STATUS reply lacks field {exc.args[0]}") from None


def parse_environment(reply: Reply) -> Environment:
    """Typed view of an ENV reply."""
    named = reply.named()
    try:
        return Environment(float(named["TEMP_C"]), float(named["RH"]))
    except KeyError as exc:
        raise ValueError(f"ENV reply lacks field {exc.args[0]}") from None


def parse_state_event(event: Event) -> CannonState:
    """The new state of a `! STATE S=...` event."""
    return CannonState(event.named()["S"])
