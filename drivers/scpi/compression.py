"""The barrel-compression tester (driver `scpi-compression`): a load cell read at a fixed squeeze.

Implements rig.core.devices.CompressionTester over a VISA TCPIP SOCKET resource
(rig.drivers.scpi.compression_codec has the wire). Each reading sets the displacement, checks the
error queue, then asks MEAS:COMP? with a timeout long enough for the fixture to close and back off.
A malformed reply, an error reply or silence is one DeviceError line naming the cause; nothing is
guessed.
"""

from __future__ import annotations

from typing import Any, Self

from rig.core.devices import BarrelCompression
from rig.core.errors import DeviceRefused, GarbledReply
from rig.drivers.registry import DriverContext
from rig.drivers.scpi import compression_codec as codec
from rig.drivers.scpi.counter_codec import ScpiErrorReply
from rig.drivers.scpi.instrument import ScpiInstrument
from rig.drivers.scpi.visa import VisaLink

OPTIONS: dict[str, type | tuple[type, ...]] = {
    "displacement_in": (int, float),
    "measure_timeout_s": (int, float),
}


class ScpiCompressionTester(ScpiInstrument):
    """A barrel-compression tester on a VISA resource: identify, measure_compression, close."""

    DRIVER = "scpi-compression"

    def __init__(
        self,
        link: VisaLink,
        displacement_in: float = codec.DISPLACEMENT_IN,
        measure_timeout_s: float = codec.MEASURE_TIMEOUT_S,
    ) -> None:
        self.link = link
        self.name = link.device
        self.displacement_in = codec.check_displacement(float(displacement_in))
        self.measure_timeout_s = float(measure_timeout_s)

    @classmethod
    def from_context(cls, context: DriverContext) -> Self:
        """The rig config's `[devices.compression] driver = "scpi-compression"`: a VISA resource."""
        options: dict[str, Any] = context.only_options(OPTIONS)
        displacement = float(options.get("displacement_in", codec.DISPLACEMENT_IN))
        timeout = float(options.get("measure_timeout_s", codec.MEASURE_TIMEOUT_S))
        try:
            codec.check_displacement(displacement)
        except ValueError as exc:
            raise context.refuse(f"displacement_in: {exc}") from None
        if not 1.0 <= timeout <= 600.0:
            raise context.refuse(f"measure_timeout_s {timeout:g} outside 1-600 s")
        link = VisaLink(
            context.address,
            device=context.name,
            timeout_s=context.timeouts.reply_s,
            on_traffic=context.on_traffic,
        )
        return cls(link, displacement, timeout).checked()

    def measure_compression(self) -> BarrelCompression:
        """Squeeze to the fixed displacement and read the force (DeviceError, one line, if it cannot)."""
        self.link.write("*CLS")
        self.link.write(codec.configure_command(self.displacement_in))
        self._check_errors(codec.configure_command(self.displacement_in))
        reply = self.link.query(codec.MEASURE, self.measure_timeout_s)
        try:
            return codec.parse_reading(reply, self.displacement_in)
        except ScpiErrorReply as exc:
            raise DeviceRefused(self.name, codec.MEASURE, str(exc.code), exc.text) from None
        except ValueError as exc:
            raise GarbledReply(self.name, f"{codec.MEASURE} reply: {exc}") from None
