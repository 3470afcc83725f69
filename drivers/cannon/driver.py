"""Air-cannon driver: the host side of drivers/cannon/codec.py over a LineTransport.

Every command the codec's state table limits is checked against it on a fresh STATUS first: the
driver refuses ARM and FIRE (SafetyRefusal), PSET and RESET (NotSent, code STATE, as the device
would answer) without sending them, and the device refuses again if the driver is wrong.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rig.core.devices import CannonStatus, Environment
from rig.core.errors import DeviceError, NotSent, ParameterError, SafetyRefusal
from rig.drivers.base import LineDriver
from rig.drivers.cannon import codec
from rig.drivers.registry import DriverContext
from rig.drivers.transport import SerialLike, TrafficRecord
from rig.drivers.wire import Event


class CannonDriver(LineDriver):
    """The air cannon (implements rig.core.devices.Cannon)."""

    NAME = "cannon"
    SPECS = codec.SPECS

    def __init__(
        self,
        port: str | SerialLike,
        *,
        name: str | None = None,
        reply_timeout_s: float = 0.5,
        ready_timeout_s: float = 120.0,
        fire_timeout_s: float = 2.0,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        reopen: Callable[[], SerialLike] | None = None,
    ) -> None:
        super().__init__(
            port, name=name, reply_timeout_s=reply_timeout_s, on_traffic=on_traffic, reopen=reopen
        )
        self.ready_timeout_s = ready_timeout_s  # filling the tank to the setpoint
        self.fire_timeout_s = fire_timeout_s  # FIRE accepted -> `! FIRED`

    @classmethod
    def _context_kwargs(cls, context: DriverContext) -> dict[str, Any]:
        return {"ready_timeout_s": context.timeouts.pressure_ready_s}

    def status(self) -> CannonStatus:
        """A fresh STATUS: state, pressure, setpoint, interlocks, shot count."""
        return self._parse(codec.parse_status, self.transport.request("STATUS"), "STATUS reply")

    def set_pressure(self, kpa: float, wait_ready: bool = True) -> None:
        """Set the tank setpoint (SAFE only); with `wait_ready`, wait for `! READY` at it."""
        try:
            codec.SPECS["PSET"].check(kpa)  # a bad setpoint is refused before anything is sent
        except ValueError as exc:
            raise ParameterError(f"{self.name} PSET", (kpa,), str(exc)) from None
        self._check_state("PSET")
        self.transport.clear_events(("READY", "FAULT"))
        self.transport.request("PSET", kpa)
        if not wait_ready:
            return
        ready = self._ready_at(float(kpa))
        event = self.transport.wait_event(("READY", "FAULT"), self.ready_timeout_s, ready)
        self._raise_fault(event, "PSET")

    def load_ball(self, ball_id: str) -> None:
        """Tell the cannon which ball is in the breech (SAFE only): its id names one physical ball."""
        try:
            codec.SPECS["LOAD"].check(ball_id)
        except ValueError as exc:
            raise ParameterError(f"{self.name} LOAD", (ball_id,), str(exc)) from None
        self._check_state("LOAD")
        self.transport.request("LOAD", ball_id)

    def arm(self) -> None:
        """SAFE -> ARMED; refused without sending ARM unless the state table allows it now."""
        reason = codec.refuse_arm(self.status())
        if reason is not None:
            raise SafetyRefusal(self.name, f"ARM not sent: {reason}")
        self.transport.request("ARM")

    def fire(self) -> int:
        """Fire and return the shot number; refused without sending FIRE unless ARMED and safe."""
        reason = codec.refuse_fire(self.status())
        if reason is not None:
            raise SafetyRefusal(self.name, f"FIRE not sent: {reason}")
        self.transport.clear_events(("FIRED", "FAULT"))
        self.transport.request("FIRE")
        event = self.transport.wait_event(("FIRED", "FAULT"), self.fire_timeout_s)
        self._raise_fault(event, "FIRE")
        return self._parse(lambda e: int(e.named()["SHOT"]), event, "FIRED event")

    def vent(self) -> None:
        """Dump the tank and return to SAFE (always allowed)."""
        self.transport.request("VENT")

    def reset(self) -> None:
        """FAULT -> SAFE; refused without sending RESET unless in FAULT."""
        self._check_state("RESET")
        self.transport.request("RESET")

    def environment(self) -> Environment:
        """Lab temperature and relative humidity."""
        return self._parse(codec.parse_environment, self.transport.request("ENV"), "ENV reply")

    def _check_state(self, verb: str) -> None:
        """Refuse `verb` unsent (NotSent) if the state table forbids it in the state STATUS reports."""
        if codec.state_limited(verb):
            reason = codec.refuse_in_state(verb, self.status().state)
            if reason is not None:
                raise NotSent(self.name, verb, reason)

    def _ready_at(self, setpoint_kpa: float) -> Callable[[Event], bool]:
        """Accept a FAULT, or a READY at this setpoint (skipping a late one for an older setpoint)."""

        def accept(event: Event) -> bool:
            if event.name == "FAULT":
                return True
            pressure = self._parse(lambda e: float(e.named()["P"]), event, "READY event")
            return setpoint_kpa <= 0 or codec.pressure_ready(pressure, setpoint_kpa)

        return accept

    def _raise_fault(self, event: Event, during: str) -> None:
        if event.name == "FAULT":
            code = event.named().get("CODE", "?")
            raise DeviceError(self.name, f"fault {code} after {during}")
