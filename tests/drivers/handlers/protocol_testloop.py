"""``testloop://``: pyserial's loopback under another scheme, to show that any registered scheme
(as ``sim://`` will be) reaches the transport without the transport knowing about it."""

from __future__ import annotations

from urllib.parse import urlsplit

from serial import SerialException
from serial.urlhandler.protocol_loop import Serial as LoopSerial


class Serial(LoopSerial):
    """A loopback port opened as ``testloop://``."""

    def from_url(self, url: str) -> str:
        if urlsplit(url).scheme != "testloop":
            raise SerialException(f"expected testloop://, got {url!r}")
        return super().from_url("loop://")
