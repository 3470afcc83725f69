"""The light gates read by an SCPI universal counter in time-stamp mode (driver `scpi-counter`).

The counter does not stream: `arm()` configures it and sends INIT before the cannon fires,
`crossings()` fetches the shot's stamps afterwards (FETC?) and maps them to gates
(rig.drivers.scpi.counter_codec). Implements rig.core.devices.Gates.

The gates' positions (the rig config's [gates] positions_m, given through the DriverContext) let a
shot of 5 stamps be mapped: its timing tells which rebound screen was missed, or the shot is
refused as ambiguous. A driver given no positions refuses every 5-stamp shot (6 are needed).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from typing import Any, Self

from rig.core.devices import GateConfig, GateCrossing
from rig.core.errors import DeviceError, GarbledReply, UnexpectedMessage
from rig.drivers.registry import DriverContext
from rig.drivers.scpi import counter_codec as codec
from rig.drivers.scpi.instrument import ScpiInstrument
from rig.drivers.scpi.visa import VisaLink

SELF_TEST_TIMEOUT_S = 30.0  # [assumed] *TST? of a counter takes seconds; the maker's figure was not read
MAX_GARBLED_FETCHES = 3  # FETC? reads the counter's memory again; a reply garbled this often ends the shot

OPTIONS: dict[str, type | tuple[type, ...]] = {
    "expected_edges": int,
    "min_edges": int,
    "resolution_ps": (int, float),
    "trigger_level_v": (int, float),
    "impedance_ohm": (int, float),
    "measurement_timeout_s": (int, float),
    "fetch_timeout_s": (int, float),
}


class ScpiCounterGates(ScpiInstrument):
    """Three light screens OR-ed into channel 1 of a 53230A-class counter, time-stamping edges."""

    DRIVER = "scpi-counter"

    def __init__(
        self,
        link: VisaLink,
        setup: codec.CounterSetup,
        *,
        fetch_timeout_s: float | None = None,
        gate_positions_m: Sequence[float] | None = None,
    ) -> None:
        self.link = link
        self.setup = setup
        # gate 1 farthest, from the impact point: what tells a 5-stamp shot's missed screen
        self.gate_positions_m = None if gate_positions_m is None else tuple(gate_positions_m)
        self.name = link.device
        self.fetch_timeout_s = fetch_timeout_s or setup.measurement_timeout_s + link.timeout_s
        self._armed = False
        self._fetched = False
        self._garbled = 0

    @classmethod
    def from_context(cls, context: DriverContext) -> Self:
        """The rig config's `[devices.gates] driver = "scpi-counter"`: a VISA resource and options."""
        options: dict[str, Any] = context.only_options(OPTIONS)
        fetch = options.pop("fetch_timeout_s", None)
        try:
            setup = codec.CounterSetup(**{k: v for k, v in options.items()})
        except ValueError as exc:
            raise context.refuse(str(exc)) from None
        if fetch is not None and not 0.05 <= fetch <= 600.0:
            raise context.refuse(f"fetch_timeout_s {fetch} outside 0.05-600 s")
        link = VisaLink(context.address, device=context.name, timeout_s=context.timeouts.reply_s,
                        on_traffic=context.on_traffic)  # fmt: skip
        return cls(link, setup, fetch_timeout_s=fetch, gate_positions_m=context.gate_positions_m).checked()

    def config(self) -> GateConfig:
        """Three gates; ticks of the counter's resolution, 48 bits (stamps never wrap in a shot)."""
        return self.setup.gate_config()

    def self_test(self) -> None:
        """`*CLS`, `*TST?` (0 passes), then the error queue must be empty."""
        self.link.write("*CLS")
        result = self._parse(codec.parse_self_test, self.link.query("*TST?", SELF_TEST_TIMEOUT_S), "*TST?")
        if result != 0:
            raise DeviceError(self.name, f"counter self-test failed: *TST? returned {result}")
        self._check_errors("*TST?")

    def arm(self) -> None:
        """Configure the time-stamp measurement and INIT (before FIRE). The error query after INIT
        is answered only once the counter has taken every line before it: the counter is waiting for
        edges when arm() returns, and an error in the configuration is refused (ABORt) here."""
        self._armed = self._fetched = False
        self._garbled = 0
        self.link.write("*CLS")
        for line in codec.configure_commands(self.setup):
            self.link.write(line)
        self.link.write("INIT")
        try:
            self._check_errors("configuration and INIT")
        except DeviceError:
            self.link.write("ABOR")
            raise
        self._armed = True

    def disarm(self) -> None:
        """ABORt a measurement still waiting (after a fetch it changes nothing)."""
        self._armed = False
        self.link.write("ABOR")

    def crossings(self, timeout_s: float) -> Iterator[GateCrossing]:
        """The shot's crossings, fetched once per arm. `timeout_s` is unused: the counter itself
        waits up to its measurement timeout, and the fetch up to `fetch_timeout_s`.

        GarbledReply for an unreadable reply (the next call fetches again); UnexpectedMessage if
        the stamps cannot be mapped to gates (a 5-stamp shot whose timing does not say which rebound
        screen was missed among them): the shot is refused, never mended.
        """
        if not self._armed or self._fetched:
            return
        reply = self.link.query("FETC?", self.fetch_timeout_s)
        try:
            stamps = codec.parse_stamps(reply)
        except codec.ScpiErrorReply as exc:
            self._fetched = True
            raise UnexpectedMessage(self.name, f"FETC? answered with {exc}") from None
        except ValueError as exc:
            self._garbled += 1
            if self._garbled >= MAX_GARBLED_FETCHES:
                self._fetched = True
                raise UnexpectedMessage(
                    self.name, f"FETC? reply garbled {self._garbled} times: {exc}"
                ) from None
            raise GarbledReply(self.name, f"FETC? reply: {exc}") from None
        self._fetched = True
        try:
            mapped = codec.map_stamps(stamps, self.setup, self.gate_positions_m)
        except codec.StampError as exc:
            raise UnexpectedMessage(self.name, f"shot refused: {exc}") from None
        received = time.monotonic()
        for crossing in mapped:
            yield GateCrossing(crossing.gate, crossing.tick, received)

    def reconnect(self) -> None:
        """Open the VISA resource again (after DeviceGone)."""
        self.link.reconnect()
