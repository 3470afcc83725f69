"""SimCannon: the air cannon's device side, with the state table of drivers/cannon/codec.py.

Which command each state accepts, and the state it leads to, come from the codec's STATE_TABLE
(a command it refuses there gets `ERR STATE`). ARM and FIRE are further decided by the codec's
`refuse_arm` / `refuse_fire`, fed the same CannonStatus a STATUS reply would carry; only the
choice of error code is local. After a shot the valve closes
(FIRED -> SAFE) and the compressor refills the tank to the setpoint on its own, announcing READY.
Every state change is announced with `! STATE S=`.

The commands' logic (`pset`, `arm`, `fire`, `vent`, `reset`) is one set of methods that every wire
front end calls: the line handler below and the Modbus PLC twin (simulators/instruments). Each
returns a `Refusal` or None, and calls `accepted()` at the moment it accepts (the line handler
answers OK there, so the reply goes before the events the command causes).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, ClassVar

from rig.core.devices import CannonState, CannonStatus, Interlocks
from rig.drivers.cannon.codec import (
    SPECS,
    interlock_fields,
    next_state,
    refuse_arm,
    refuse_fire,
    refuse_in_state,
)
from rig.drivers.codec import CheckedCommand
from rig.simulators.device import SimDevice

if TYPE_CHECKING:
    from rig.simulators.world import SimWorld

Refusal = tuple[str, str]  # (error code, reason), as an `ERR` reply carries them


def _nothing() -> None:
    """Acceptance needs no answer (a front end that answers after the command is done)."""


class SimCannon(SimDevice):
    """The simulated air cannon."""

    name = "cannon"
    specs = SPECS
    identity: ClassVar[dict[str, str]] = {"MODEL": "SIM-CANNON", "FW": "sim-1", "SN": "SIM-C001"}

    def __init__(self, world: SimWorld) -> None:
        super().__init__(world)
        self.state = CannonState.SAFE
        self.setpoint = 0.0
        self.fired = 0  # balls launched (STATUS SHOTS=)
        self.fault_code = ""  # the last FAULT's code (MISFIRE), until RESET
        self.ready_at: float | None = None  # virtual time the pending fill announces READY
        # The tank pressure is a ramp: p_from until t_from, then towards the setpoint at the fill rate.
        self._p_from, self._t_from = 0.0, 0.0

    # -- state ------------------------------------------------------------------------------
    def pressure(self, time_s: float | None = None) -> float:
        """Tank pressure at virtual time `time_s` (default now), kPa."""
        t = self.world.clock if time_s is None else time_s
        gap = self.setpoint - self._p_from
        moved = max(0.0, t - self._t_from) * self.world.scene.cannon.fill_rate_kpa_s
        return self.setpoint if moved >= abs(gap) else self._p_from + (moved if gap > 0 else -moved)

    def status(self) -> CannonStatus:
        """What a STATUS reply says now (pressures to 0.1 kPa, as on the wire)."""
        pressure, setpoint = round(self.pressure(), 1), round(self.setpoint, 1)
        return CannonStatus(self.state, pressure, setpoint, self.world.interlocks(), self.fired)

    def _set_state(
        self, state: CannonState, at: float | None = None, tag: str | None = None, shot: int = 0
    ) -> None:
        def apply() -> None:
            self.state = state

        if at is None:
            apply()
        else:
            self.world.at(at, apply, tag)
        self.emit("STATE", {"S": state.value}, at=at, tag=tag, shot=shot)

    def _refill(self, start_s: float, p_start: float) -> None:
        """Fill from p_start at start_s towards the setpoint; READY when settled."""
        cannon = self.world.scene.cannon
        self.world.cancel("refill")
        self._p_from, self._t_from = p_start, start_s
        ready = start_s + abs(self.setpoint - p_start) / cannon.fill_rate_kpa_s + cannon.settle_s
        self.ready_at = ready
        self.emit("READY", {"P": round(self.setpoint, 1)}, at=ready, tag="refill")

    def _vent(self) -> None:
        self.world.cancel("refill")
        self.world.cancel("cycle")
        self.ready_at = None
        self.setpoint = 0.0
        self._p_from, self._t_from = 0.0, self.world.clock

    def interlocks_changed(self, ilk: Interlocks, at: float | None, tag: str | None = None) -> None:
        """The loop changed (now, or at `at`): announce it; an opening while ARMED vents to SAFE."""
        self.emit("ILK", interlock_fields(ilk), at=at, tag=tag)
        if at is None and self.state is CannonState.ARMED and not ilk.all_closed:
            self._vent()
            self._set_state(CannonState.SAFE)

    # -- commands ---------------------------------------------------------------------------
    def handle(self, cmd: CheckedCommand) -> None:
        """Act on one command."""
        verb = cmd.verb
        if (reason := refuse_in_state(verb, self.state)) is not None:
            return self.refuse(cmd, "STATE", reason)
        refusal: Refusal | None = None
        accepted = functools.partial(self.ok, cmd)
        if verb == "STATUS":
            s = self.status()
            fields = {"STATE": s.state.value, "P": s.pressure_kpa, "SET": s.setpoint_kpa}
            self.ok(cmd, {**fields, **interlock_fields(s.interlocks), "SHOTS": s.shots})
        elif verb == "PSET":
            refusal = self.pset(float(cmd.values[0]), accepted)  # type: ignore[arg-type]
        elif verb == "LOAD":
            self.world.load_ball(str(cmd.values[0]))
            self.ok(cmd)
        elif verb == "ARM":
            refusal = self.arm(accepted)
        elif verb == "FIRE":
            refusal = self.fire(accepted)
        elif verb == "VENT":
            self.vent(accepted)
        elif verb == "RESET":
            refusal = self.reset(accepted)
        elif verb == "ENV":
            temp, rh = self.world.lab.environment(self.world.clock)
            self.ok(cmd, {"TEMP_C": round(temp, 2), "RH": round(rh, 1)})
        else:
            super().handle(cmd)
        if refusal is not None:
            self.refuse(cmd, *refusal)
        return None

    # -- the commands' logic, shared by every front end -------------------------------------
    def pset(self, kpa: float, accepted: Callable[[], None] = _nothing) -> Refusal | None:
        """New setpoint (SAFE only); the tank fills or bleeds towards it, READY when settled."""
        if (reason := refuse_in_state("PSET", self.state)) is not None:
            return ("STATE", reason)
        p_now = self.pressure()
        self.setpoint = float(kpa)
        accepted()
        self._refill(self.world.clock, p_now)
        return None

    def vent(self, accepted: Callable[[], None] = _nothing) -> None:
        """Dump the tank; to SAFE (always allowed)."""
        self._vent()
        accepted()
        if (after := next_state("VENT", self.state)) is not self.state:
            self._set_state(after)

    def reset(self, accepted: Callable[[], None] = _nothing) -> Refusal | None:
        """FAULT -> SAFE."""
        if (reason := refuse_in_state("RESET", self.state)) is not None:
            return ("STATE", reason)
        accepted()
        self.fault_code = ""
        self._set_state(next_state("RESET", self.state))
        return None

    def arm(self, accepted: Callable[[], None] = _nothing) -> Refusal | None:
        """SAFE -> ARMED, as the codec's refuse_arm allows."""
        status = self.status()
        reason = refuse_arm(status)
        if reason is not None:
            return (_code(status, CannonState.SAFE, "PRESSURE"), reason)
        accepted()
        self._set_state(next_state("ARM", status.state))
        self.world.after_arm(self.world.attempts + 1)
        return None

    def fire(self, accepted: Callable[[], None] = _nothing) -> Refusal | None:
        """ARMED -> FIRED and the ball is away, as the codec's refuse_fire allows (or a misfire)."""
        status = self.status()
        reason = refuse_fire(status)
        if reason is not None:
            return (_code(status, CannonState.ARMED, "STATE"), reason)
        world = self.world
        world.attempts += 1
        shot = world.attempts
        accepted()
        if world.misfires(shot):
            self._vent()
            self.fault_code = "MISFIRE"
            self.emit("FAULT", {"CODE": "MISFIRE"}, shot=shot)
            self._set_state(CannonState.FAULT, shot=shot)
            return None
        pressure = self.pressure()
        self.fired += 1
        self._set_state(next_state("FIRE", status.state), shot=shot)
        self.emit("FIRED", {"SHOT": self.fired}, shot=shot)
        world.fire(pressure, shot)
        # The tank is empty once the ball is away; the valve closes, then the compressor refills.
        closed = world.clock + world.scene.cannon.valve_close_s
        self._p_from, self._t_from = 0.0, closed
        self._set_state(CannonState.SAFE, at=closed, tag="cycle", shot=shot)
        self._refill(closed, 0.0)
        world.after_shot(shot)
        return None


def _code(status: CannonStatus, needed: CannonState, otherwise: str) -> str:
    """The error code for a refusal, checked in the table's own order: state, interlocks, rest."""
    if status.state is not needed:
        return "STATE"
    if not status.interlocks.all_closed:
        return "ILK"
    return otherwise
