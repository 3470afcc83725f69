"""A simulated barrel-compression tester on a raw TCP port, squeezing the world's barrel.

It speaks rig.drivers.scpi.compression_codec's lines. MEAS:COMP? reads the force of the world's
softening barrel (rig.simulators.effects.softening) at the configured displacement, with the load
cell's noise; a world whose barrel does not soften has nothing to squeeze (error -241, "Hardware
missing", as the reply).

Fault options (n = the n-th MEAS:COMP?, 1-based; 0 = never): `silent_on` never answers it,
`garble_on` spoils one byte of its reply, `slip_on` reports the anvils short of the displacement.
"""

from __future__ import annotations

import threading
from typing import Any, ClassVar

from rig.core.devices import BarrelCompression
from rig.drivers.scpi import compression_codec as codec
from rig.simulators.instruments.lineserver import LineServer
from rig.simulators.world import SimWorld

IDN = "bat-rig simulator,BCT-SIM,SIM-B001,sim-1"
FAULTS = ("silent_on", "garble_on", "slip_on")


class CompressionTesterTwin:
    """The tester: `start()` serves it on a local port; `device_table()` is its rig config table."""

    DRIVER: ClassVar[str] = "scpi-compression"
    KIND: ClassVar[str] = "compression"

    def __init__(self, world: SimWorld, **fault_options: Any) -> None:
        unknown = sorted(set(fault_options) - set(FAULTS))
        if unknown:
            raise ValueError(
                f"scpi-compression twin has no option {unknown[0]!r} (it takes: {', '.join(FAULTS)})"
            )
        self.world = world
        self.faults = {k: int(v) for k, v in fault_options.items()}
        self.displacement_in = codec.DISPLACEMENT_IN
        self.errors: list[tuple[int, str]] = []
        self.measured = 0  # MEAS:COMP? queries so far
        self.readings: list[BarrelCompression] = []  # every reading sent (tests compare with the truth)
        self.received: list[str] = []
        self._lock = threading.Lock()
        self._server = LineServer(self.handle, "scpi-compression")
        self.address = ""

    def handle(self, line: str) -> str | None:
        """One program message -> its reply line, or None."""
        with self._lock:
            self.received.append(line)
            cmd = codec.parse(line)
            if cmd is None:
                self.errors.append((-113, "Undefined header"))
                return None
            h = cmd.header
            if h == "*IDN?":
                return IDN
            if h == "*RST":
                self.displacement_in = codec.DISPLACEMENT_IN
            elif h == "*CLS":
                self.errors.clear()
            elif h == "SYSTem:ERRor?":
                code, text = self.errors.pop(0) if self.errors else (0, "No error")
                return f'{code:+d},"{text}"'
            elif h == "CONFigure:DISPlacement":
                try:
                    self.displacement_in = codec.check_displacement(float(cmd.argument))
                except ValueError:
                    self.errors.append((-222, "Data out of range"))
            elif h == "MEASure:COMPression?":
                return self._measure()
            return None

    def _measure(self) -> str | None:
        self.measured += 1
        n = self.measured
        barrel = self.world.barrel
        if barrel is None:
            return '-241,"Hardware missing"'
        if n == self.faults.get("silent_on", 0):
            return None
        with self.world.lock:
            force = max(0.0, barrel.read_force_lbf(self.displacement_in))
        reached = self.displacement_in - (0.01 if n == self.faults.get("slip_on", 0) else 0.0)
        reading = BarrelCompression(force_lbf=force, displacement_in=reached)
        self.readings.append(reading)
        reply = codec.format_reading(reading)
        if n == self.faults.get("garble_on", 0):
            reply = reply[:3] + "\x9f" + reply[4:]
        return reply

    def start(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Listen on `host:port` (0: any free port); the VISA resource to open."""
        bound = self._server.start(host, port)
        self.address = f"TCPIP0::{host}::{bound}::SOCKET"
        return self.address

    def device_table(self) -> dict[str, Any]:
        """The `[devices.compression]` table of a rig config that uses this twin."""
        if not self.address:
            raise RuntimeError("the twin is not serving yet: it has no address")
        return {"driver": self.DRIVER, "address": self.address, "simulated": True}

    def close(self) -> None:
        """Stop listening and hang up."""
        self._server.close()
