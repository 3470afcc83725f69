"""Pivot-clamp driver: the host side of drivers/clamp/codec.py over a LineTransport.

Every motion is confirmed by the device's own sensor event (`! LOCK`, `! POS`, `! PERIOD`), not
by the command's OK, which only means the command was accepted.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from rig.core.devices import ClampStatus, PendulumPeriod, Recoil
from rig.core.errors import DeviceError, DeviceTimeout
from rig.drivers.base import LineDriver
from rig.drivers.clamp import codec
from rig.drivers.codec import flag
from rig.drivers.registry import DriverContext
from rig.drivers.transport import SerialLike, TrafficRecord
from rig.drivers.wire import Event


class ClampDriver(LineDriver):
    """The pivot clamp, its impact-point stage and angle encoder (implements rig.core.devices.Clamp)."""

    NAME = "clamp"
    SPECS = codec.SPECS
    OPTIONS: ClassVar[Mapping[str, type]] = {"recoil_encoder": bool}

    def __init__(
        self,
        port: str | SerialLike,
        *,
        name: str | None = None,
        reply_timeout_s: float = 0.5,
        lock_timeout_s: float = 5.0,
        move_timeout_s: float = 60.0,
        swing_timeout_s: float = 10.0,
        swing_cycle_timeout_s: float = 3.0,
        position_tolerance_mm: float = 0.5,
        recoil_encoder: bool = True,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        reopen: Callable[[], SerialLike] | None = None,
    ) -> None:
        super().__init__(
            port, name=name, reply_timeout_s=reply_timeout_s, on_traffic=on_traffic, reopen=reopen
        )
        self.lock_timeout_s = lock_timeout_s  # CLAMP/RELEASE -> `! LOCK`
        self.move_timeout_s = move_timeout_s  # MOVE -> `! POS` over the whole stage travel
        self.swing_timeout_s = swing_timeout_s  # SWING n -> `! PERIOD`: this plus n cycles
        self.swing_cycle_timeout_s = swing_cycle_timeout_s
        self.position_tolerance_mm = position_tolerance_mm
        self.recoil_encoder = recoil_encoder  # False: a clamp with no pivot encoder sends no `! RECOIL`

    @classmethod
    def _context_kwargs(cls, context: DriverContext) -> dict[str, Any]:
        """[devices.clamp] options: recoil_encoder = false for a clamp that reports no recoil."""
        return {"recoil_encoder": bool(context.options.get("recoil_encoder", True))}

    def status(self) -> ClampStatus:
        """A fresh STATUS: lock, stage position, moving, pivot angle."""
        return self._parse(codec.parse_status, self.transport.request("STATUS"), "STATUS reply")

    def clamp(self) -> None:
        """Close the grip and wait until the lock sensor confirms (`! LOCK L=1`)."""
        self._lock(True)

    def release(self) -> None:
        """Open the grip and wait until the lock sensor confirms (`! LOCK L=0`)."""
        self._lock(False)

    def move_to(self, mm: float) -> None:
        """Set the impact point's distance from the pivot and wait for `! POS` there."""
        self.transport.clear_events("POS")
        self.transport.request("MOVE", mm)
        event = self.transport.wait_event("POS", self.move_timeout_s)
        reached = self._parse(lambda e: float(e.named()["MM"]), event, "POS event")
        if abs(reached - float(mm)) > self.position_tolerance_mm:
            raise DeviceError(self.name, f"stage stopped at {reached:g} mm, asked for {float(mm):g} mm")

    def measure_period(self, cycles: int) -> PendulumPeriod:
        """Swing the bat as a pendulum and time `cycles` periods (ASTM F2398)."""
        self.transport.clear_events("PERIOD")
        self.transport.request("SWING", cycles)
        timeout = self.swing_timeout_s + int(cycles) * self.swing_cycle_timeout_s
        event = self.transport.wait_event("PERIOD", timeout)
        return self._parse(codec.parse_period, event, "PERIOD event")

    def next_recoil(self, timeout_s: float) -> Recoil | None:
        """The next recoil the encoder reports after an impact, or None within `timeout_s` (at once for
        a clamp configured without an encoder: nothing is waited for that cannot come)."""
        if not self.recoil_encoder:
            return None
        try:
            event = self.transport.wait_event("RECOIL", timeout_s)
        except DeviceTimeout:
            return None
        return self._parse(codec.parse_recoil, event, "RECOIL event")

    def _lock(self, locked: bool) -> None:
        self.transport.clear_events("LOCK")
        self.transport.request("CLAMP" if locked else "RELEASE")
        self.transport.wait_event("LOCK", self.lock_timeout_s, self._lock_is(locked))

    def _lock_is(self, locked: bool) -> Callable[[Event], bool]:
        def accept(event: Event) -> bool:
            return self._parse(lambda e: flag(e.named()["L"]), event, "LOCK event") is locked

        return accept
