"""What every SCPI instrument on a VISA link does alike: say what it is, report its error queue, and
refuse a reply it cannot parse in one line (GarbledReply naming the query)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Self, TypeVar

from rig.core.devices import InstrumentIdentity
from rig.core.errors import DeviceRefused, GarbledReply
from rig.drivers.scpi.counter_codec import parse_error, parse_idn
from rig.drivers.scpi.visa import VisaLink

T = TypeVar("T")


class ScpiInstrument:
    """The shared part of the SCPI drivers: `link` (a VisaLink) and `name` (the device's)."""

    link: VisaLink
    name: str

    def identify(self) -> InstrumentIdentity:
        """`*IDN?`: maker, model, serial number, firmware."""
        return self._parse(parse_idn, self.link.query("*IDN?"), "*IDN?")

    def checked(self) -> Self:
        """This instrument once it has said what it is (a raw socket opens even where nothing
        listens: ask before any run); closed if it cannot."""
        try:
            self.identify()
        except BaseException:
            self.close()
            raise
        return self

    def close(self) -> None:
        """Close the VISA resource."""
        self.link.close()

    def _check_errors(self, after: str) -> None:
        """DeviceRefused (naming `after`) if the error queue holds an error."""
        code, text = self._parse(parse_error, self.link.query("SYST:ERR?"), "SYST:ERR?")
        if code != 0:
            raise DeviceRefused(self.name, after, str(code), text)

    def _parse(self, parse: Callable[[str], T], reply: str, what: str) -> T:
        try:
            return parse(reply)
        except ValueError as exc:
            raise GarbledReply(self.name, f"{what} reply: {exc}") from None
