"""An example of a lab's own driver: the rig's line-protocol gates, corrected for each screen's
measured trigger delay.

A light screen fires a little after the ball's nose reaches its beam; a lab that has measured the
delay of each screen (ns, e.g. with a chronograph and two speeds) gives it as an option:

    [devices.gates]
    driver = "lab-gates"
    address = "/dev/ttyUSB1"
    options = { delay_ns = [120.0, 95.0, 110.0] }

The driver subtracts each gate's delay from its counter ticks, so the speeds are those of the
ball. Everything else (the wire, the traffic record, identity) is bat-rig's own gates driver.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Self

from rig.core.devices import GateCrossing
from rig.drivers.gates.driver import GatesDriver
from rig.drivers.registry import DriverContext


class LatencyCorrectedGates(GatesDriver):
    """Gates whose counter ticks are corrected by each screen's trigger delay."""

    @classmethod
    def from_context(cls, context: DriverContext) -> Self:
        """The entry point: the rig config's address, timeouts and `delay_ns` (one per gate)."""
        options = context.only_options({"delay_ns": list})
        delays = options.get("delay_ns", [0.0, 0.0, 0.0])
        if len(delays) != 3 or not all(isinstance(d, int | float) and 0 <= d < 1e6 for d in delays):
            raise context.refuse("option 'delay_ns' must be three delays in ns, 0 to 1e6, one per gate")
        gates = cls(
            context.address,
            name=context.kind,
            reply_timeout_s=context.timeouts.reply_s,
            on_traffic=context.on_traffic,
        )
        gates.delays_ns = tuple(float(d) for d in delays)
        return gates

    delays_ns: tuple[float, ...] = (0.0, 0.0, 0.0)

    def crossings(self, timeout_s: float) -> Iterator[GateCrossing]:
        """The line driver's crossings, each moved earlier by its gate's delay (whole ticks)."""
        counter = self._config or self.config()
        for crossing in super().crossings(timeout_s):
            shift = round(self.delays_ns[crossing.gate - 1] / counter.tick_ns)
            yield GateCrossing(crossing.gate, (crossing.tick - shift) % counter.modulus, crossing.host_time_s)
