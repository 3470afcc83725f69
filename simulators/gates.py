"""SimGates: three light gates on one counter-timer, streaming `! G N= T=` while armed."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar

from rig.drivers.codec import CheckedCommand
from rig.drivers.gates.codec import SPECS
from rig.simulators.device import SimDevice
from rig.simulators.records import Crossing

if TYPE_CHECKING:
    from rig.simulators.world import SimWorld


class SimGates(SimDevice):
    """The simulated light gates and their counter."""

    name = "gates"
    specs = SPECS
    identity: ClassVar[dict[str, str]] = {"MODEL": "SIM-GATES", "FW": "sim-1", "SN": "SIM-G001"}

    def __init__(self, world: SimWorld) -> None:
        super().__init__(world)
        self.armed = False

    def handle(self, cmd: CheckedCommand) -> None:
        """Act on one command."""
        rig = self.world.scene.rig
        if cmd.verb == "CFG":
            self.ok(cmd, {"N": len(rig.gate_positions_m), "TICK_NS": rig.tick_ns, "BITS": rig.counter_bits})
        elif cmd.verb == "ARM":
            self.armed = True
            self.ok(cmd)
        elif cmd.verb == "DISARM":
            self.armed = False
            self.ok(cmd)
            self.world.cancel("beam")  # breaks that have not happened yet will not be streamed
        elif cmd.verb == "TEST":
            self.ok(cmd, {"RESULT": "PASS"})
        elif cmd.verb == "CLOCK":
            self.ok(cmd, {"T": self.world.counter(round(self.world.clock / (rig.tick_ns * 1e-9)))})
        else:
            super().handle(cmd)

    def stream(self, crossings: Sequence[Crossing], ticks: Sequence[tuple[int, int]], shot: int) -> None:
        """Queue one `! G` event per beam break, at its virtual time, if the gates are armed."""
        if not self.armed:
            return
        for crossing, (gate, tick) in zip(crossings, ticks, strict=True):
            self.emit("G", {"N": gate, "T": tick}, at=crossing.time_s, tag="beam", shot=shot)
