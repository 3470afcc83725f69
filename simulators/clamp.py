"""SimClamp: the pivot clamp - grip and lock sensor, impact-point stage, pivot encoder."""

from __future__ import annotations

import math
from collections.abc import Callable
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
        # The stage moves from _mm_from (at _t_from) to _mm_to (at _t_to) at constant speed.
        self._mm_from, self._mm_to, self._t_from, self._t_to = start, start, 0.0, 0.0
        self._swing_from = self._swing_until = -1.0
        # other wire front ends on this clamp (an instrument twin) hear each recoil: (omega, at, shot)
        self.recoil_listeners: list[Callable[[float, float, int], None]] = []

    def position_mm(self, time_s: float | None = None) -> float:
        """Impact point's distance from the pivot at `time_s` (default now), mm."""
        t = self.world.clock if time_s is None else time_s
        if t >= self._t_to:
            return self._mm_to
        if t <= self._t_from:
            return self._mm_from
        done = (t - self._t_from) / (self._t_to - self._t_from)
        return self._mm_from + (self._mm_to - self._mm_from) * done

    def _arrival(self) -> float:
        return self._t_to

    def start_move(self, mm: float, duration_s: float | None = None) -> float:
        """Send the stage towards `mm` now (at the scene's speed, or taking `duration_s`); its arrival."""
        now = self.world.clock
        start = self.position_mm()
        if duration_s is None:
            duration_s = abs(mm - start) / self.world.scene.rig.stage_speed_mm_s
        self._mm_from, self._mm_to, self._t_from, self._t_to = start, float(mm), now, now + duration_s
        return self._t_to

    def _busy(self) -> str | None:
        now = self.world.clock
        if now < self._arrival():
            return "stage moving"
        if now < self._swing_until:
            return "swinging"
        return None

    def angle_deg(self) -> float:
        """The encoder's angle now: a decaying-free swing while timing, else at rest."""
        return self.angle_at(self.world.clock)

    def angle_at(self, time_s: float) -> float:
        """The pivot's true angle at `time_s` (given the swing started so far), deg."""
        if not self._swing_from <= time_s < self._swing_until:
            return 0.0
        phase = 2.0 * math.pi * (time_s - self._swing_from) / self.world.swing_period()
        return self.world.scene.rig.swing_amplitude_deg * math.cos(phase)

    def grip(self, locked: bool) -> float:
        """Close or open the grip now; the time its lock sensor agrees (the interlock follows)."""
        world = self.world
        world.cancel("lock")
        world.cancel_interlock("clamp")
        if not locked:
            world.cancel("swing")
            self._swing_until = -1.0
            if self.locked:
                world.set_interlock("clamp", False)
            return world.clock
        when = world.clock + (0.0 if self.locked else world.scene.rig.lock_time_s)
        if not self.locked:
            world.set_interlock("clamp", True, at=when)
        return when

    def start_swing(self, cycles: int) -> float:
        """Lift and drop the bat now: it swings `cycles` periods after LIFT_S; when it is caught."""
        self._swing_from = self.world.clock + LIFT_S
        self._swing_until = self._swing_from + cycles * self.world.swing_period()
        return self._swing_until

    def handle(self, cmd: CheckedCommand) -> None:
        """Act on one command."""
        world, verb = self.world, cmd.verb
        if verb == "STATUS":
            pos, deg, moving = round(self.position_mm(), 2), round(self.angle_deg(), 2), self._arrival()
            self.ok(cmd, {"LOCK": self.locked, "POS": pos, "MOVING": world.clock < moving, "DEG": deg})
        elif verb == "CLAMP":
            self.ok(cmd)
            self.emit("LOCK", {"L": 1}, at=self.grip(True), tag="lock")
        elif verb == "RELEASE":
            self.ok(cmd)
            self.grip(False)
            self.emit("LOCK", {"L": 0})
        elif verb == "MOVE":
            busy = self._busy()
            if busy:
                return self.refuse(cmd, "BUSY", busy)
            arrival = self.start_move(float(cmd.values[0]))  # type: ignore[arg-type]
            self.ok(cmd)
            self.emit("POS", {"MM": round(self._mm_to, 2)}, at=arrival)
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
        self.start_swing(cycles)
        self.ok(cmd)
        amp = self.world.scene.rig.swing_amplitude_deg
        fields = {"US": round(period * 1e6, 1), "AMP": amp, "N": cycles}
        self.emit("PERIOD", fields, at=self._swing_until, tag="swing")
        return None

    def report_recoil(self, omega: float, at: float, shot: int) -> None:
        """Queue the encoder's `! RECOIL W=` after an impact."""
        self.emit("RECOIL", {"W": round(omega, 4)}, at=at, shot=shot)
        for listener in self.recoil_listeners:
            listener(omega, at, shot)
