"""SimClamp: the pivot clamp - grip and lock sensor, impact-point stage, pivot encoder."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

from rig.drivers.clamp.codec import SPECS
from rig.drivers.codec import CheckedCommand
from rig.simulators.device import SimDevice

if TYPE_CHECKING:
    from rig.simulators.world import SimWorld

LIFT_S = 1.0  # SWING: lifting the bat to the release angle and letting it settle


class SimClamp(SimDevice):
    """The simulated pivot clamp."""

    name = "clamp"
    specs = SPECS
    identity: ClassVar[dict[str, str]] = {"MODEL": "SIM-CLAMP", "FW": "sim-1", "SN": "SIM-P001"}

    def __init__(self, world: SimWorld) -> None:
        super().__init__(world)
        self.locked = False
        start = world.scene.rig.stage_start_mm
        # The stage moves from _mm_from (at _t_from) to _mm_to at constant speed.
        self._mm_from, self._mm_to, self._t_from = start, start, 0.0
        self._swing_from = self._swing_until = -1.0

    def position_mm(self, time_s: float | None = None) -> float:
        """Impact point's distance from the pivot at `time_s` (default now), mm."""
        t = self.world.clock if time_s is None else time_s
        span = self._mm_to - self._mm_from
        moved = max(0.0, t - self._t_from) * self.world.scene.rig.stage_speed_mm_s
        return self._mm_to if moved >= abs(span) else self._mm_from + math.copysign(moved, span)

    def _arrival(self) -> float:
        return self._t_from + abs(self._mm_to - self._mm_from) / self.world.scene.rig.stage_speed_mm_s

    def _busy(self) -> str | None:
        now = self.world.clock
        if now < self._arrival():
            return "stage moving"
        if now < self._swing_until:
            return "swinging"
        return None

    def angle_deg(self) -> float:
        """The encoder's angle now: a decaying-free swing while timing, else at rest."""
        now = self.world.clock
        if not self._swing_from <= now < self._swing_until:
            return 0.0
        phase = 2.0 * math.pi * (now - self._swing_from) / self.world.swing_period()
        return self.world.scene.rig.swing_amplitude_deg * math.cos(phase)

    def handle(self, cmd: CheckedCommand) -> None:
        """Act on one command."""
        world, verb = self.world, cmd.verb
        if verb == "STATUS":
            pos, deg, moving = round(self.position_mm(), 2), round(self.angle_deg(), 2), self._arrival()
            self.ok(cmd, {"LOCK": self.locked, "POS": pos, "MOVING": world.clock < moving, "DEG": deg})
        elif verb == "CLAMP":
            self.ok(cmd)
            world.cancel("lock")
            world.cancel_interlock("clamp")
            when = world.clock + (0.0 if self.locked else world.scene.rig.lock_time_s)
            self.emit("LOCK", {"L": 1}, at=when, tag="lock")
            if not self.locked:
                world.set_interlock("clamp", True, at=when)
        elif verb == "RELEASE":
            self.ok(cmd)
            world.cancel("lock")
            world.cancel_interlock("clamp")
            world.cancel("swing")
            self._swing_until = -1.0
            self.emit("LOCK", {"L": 0})
            if self.locked:
                world.set_interlock("clamp", False)
        elif verb == "MOVE":
            busy = self._busy()
            if busy:
                return self.refuse(cmd, "BUSY", busy)
            self._mm_from, self._mm_to, self._t_from = self.position_mm(), float(cmd.values[0]), world.clock  # type: ignore[arg-type]
            self.ok(cmd)
            self.emit("POS", {"MM": round(self._mm_to, 2)}, at=self._arrival())
        elif verb == "SWING":
            self._swing(cmd)
        else:
            super().handle(cmd)
        return None

    def _swing(self, cmd: CheckedCommand) -> None:
        if not self.locked:
            return self.refuse(cmd, "STATE", "grip not locked")
        busy = self._busy()
        if busy:
            return self.refuse(cmd, "BUSY", busy)
        cycles = int(cmd.values[0])  # type: ignore[call-overload]
        period = self.world.swing_period()
        self._swing_from = self.world.clock + LIFT_S
        self._swing_until = self._swing_from + cycles * period
        self.ok(cmd)
        amp = self.world.scene.rig.swing_amplitude_deg
        fields = {"US": round(period * 1e6, 1), "AMP": amp, "N": cycles}
        self.emit("PERIOD", fields, at=self._swing_until, tag="swing")
        return None

    def report_recoil(self, omega: float, at: float, shot: int) -> None:
        """Queue the encoder's `! RECOIL W=` after an impact."""
        self.emit("RECOIL", {"W": round(omega, 4)}, at=at, shot=shot)
