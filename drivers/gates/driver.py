"""Light-gate driver: the host side of drivers/gates/codec.py over a LineTransport.

Beam breaks are streamed as events while armed; each crossing carries the counter's tick and the
host's receive time (time.monotonic(), taken when the bytes were read, not when consumed).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from rig.core.devices import GateConfig, GateCrossing
from rig.core.errors import DeviceError, DeviceTimeout, GarbledReply
from rig.drivers.base import LineDriver
from rig.drivers.gates import codec
from rig.drivers.transport import ReceivedEvent, SerialLike, TrafficRecord


class GatesDriver(LineDriver):
    """The three light gates and their counter-timer (implements rig.core.devices.Gates)."""

    NAME = "gates"
    SPECS = codec.SPECS

    def __init__(
        self,
        port: str | SerialLike,
        *,
        name: str | None = None,
        reply_timeout_s: float = 0.5,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        reopen: Callable[[], SerialLike] | None = None,
    ) -> None:
        super().__init__(
            port, name=name, reply_timeout_s=reply_timeout_s, on_traffic=on_traffic, reopen=reopen
        )
        self._config: GateConfig | None = None

    def config(self) -> GateConfig:
        """Gate count, counter tick and width (asked afresh, then kept for checking events)."""
        self._config = self._parse(codec.parse_config, self.transport.request("CFG"), "CFG reply")
        return self._config

    def arm(self) -> None:
        """Start streaming beam breaks; crossings kept from before are forgotten (not from the log)."""
        self.transport.clear_events("G")
        self.transport.request("ARM")

    def disarm(self) -> None:
        """Stop streaming beam breaks."""
        self.transport.request("DISARM")

    def self_test(self) -> None:
        """Test every emitter and receiver; DeviceError naming the gate that failed."""
        named = self.transport.request("TEST").named()
        result = named.get("RESULT")
        if result == "PASS":
            return
        if result == "FAIL":
            raise DeviceError(self.name, f"self-test failed at gate {named.get('GATE', '?')}")
        raise GarbledReply(self.name, f"TEST reply: RESULT is {result!r}, neither PASS nor FAIL")

    def clock(self) -> int:
        """The counter's value now, in ticks."""
        return self._parse(lambda r: int(r.named()["T"]), self.transport.request("CLOCK"), "CLOCK reply")

    def crossings(self, timeout_s: float) -> Iterator[GateCrossing]:
        """Beam breaks as they arrive, with host receive times; ends when none comes within
        `timeout_s`. A malformed G event raises GarbledReply."""
        while True:
            try:
                rec = self.transport.next_event("G", timeout_s)
            except DeviceTimeout:
                return
            yield self._crossing(rec)

    def _crossing(self, rec: ReceivedEvent) -> GateCrossing:
        gates = self._config.gates if self._config else codec.N_GATES
        crossing = self._parse(lambda e: codec.parse_crossing(e, gates), rec.event, "G event")
        return GateCrossing(crossing.gate, crossing.tick, rec.t_s)
