"""SimCannon: the air cannon's device side, with the state table of drivers/cannon/codec.py.

Which command each state accepts, and the state it leads to, come from the codec's STATE_TABLE
(a command it refuses there gets `ERR STATE`). ARM and FIRE are further decided by the codec's
`refuse_arm` / `refuse_fire`, fed the same CannonStatus a STATUS reply would carry; only the
choice of error code is local. After a shot the valve closes
(FIRED -> SAFE) and the compressor refills the tank to the setpoint on its own, announcing READY.
Every state change is announced with `! STATE S=`.
"""

from __future__ import annotations

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
        self.emit("READY", {"P": round(self.setpoint, 1)}, at=ready, tag="refill")

    def _vent(self) -> None:
        self.world.cancel("refill")
        self.world.cancel("cycle")
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
        if verb == "STATUS":
            s = self.status()
            fields = {"STATE": s.state.value, "P": s.pressure_kpa, "SET": s.setpoint_kpa}
            self.ok(cmd, {**fields, **interlock_fields(s.interlocks), "SHOTS": s.shots})
        elif verb == "PSET":
            p_now = self.pressure()
            self.setpoint = float(cmd.values[0])  # type: ignore[arg-type]
            self.ok(cmd)
            self._refill(self.world.clock, p_now)
        elif verb == "LOAD":
            self.world.load_ball(str(cmd.values[0]))
            self.ok(cmd)
        elif verb == "ARM":
            self._arm(cmd)
        elif verb == "FIRE":
            self._fire(cmd)
        elif verb == "VENT":
            self._vent()
            self.ok(cmd)
            if (after := next_state(verb, self.state)) is not self.state:
                self._set_state(after)
        elif verb == "RESET":
            self.ok(cmd)
            self._set_state(next_state(verb, self.state))
        elif verb == "ENV":
            temp, rh = self.world.lab.environment(self.world.clock)
            self.ok(cmd, {"TEMP_C": round(temp, 2), "RH": round(rh, 1)})
        else:
            super().handle(cmd)
        return None

    def _arm(self, cmd: CheckedCommand) -> None:
        status = self.status()
        reason = refuse_arm(status)
        if reason is not None:
            return self.refuse(cmd, _code(status, CannonState.SAFE, "PRESSURE"), reason)
        self.ok(cmd)
        self._set_state(next_state(cmd.verb, status.state))
        self.world.after_arm(self.world.attempts + 1)
        return None

    def _fire(self, cmd: CheckedCommand) -> None:
        status = self.status()
        reason = refuse_fire(status)
        if reason is not None:
            return self.refuse(cmd, _code(status, CannonState.ARMED, "STATE"), reason)
        world = self.world
        world.attempts += 1
        shot = world.attempts
        self.ok(cmd)
        if world.misfires(shot):
            self._vent()
            self.emit("FAULT", {"CODE": "MISFIRE"}, shot=shot)
            self._set_state(CannonState.FAULT, shot=shot)
            return None
        pressure = self.pressure()
        self.fired += 1
        self._set_state(next_state(cmd.verb, status.state), shot=shot)
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
