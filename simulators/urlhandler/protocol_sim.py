"""The sim:// port: a pyserial SerialBase over one device of a SimWorld (pattern of protocol_loop).

read(size) returns at once whatever the device has queued (up to `size`); if nothing is queued it
waits on the world's condition variable up to the port timeout, then returns b''. An unplug fault
makes read, write and in_waiting raise SerialException('device unplugged') until the port is
closed and opened again (which plugs the device back in).
"""

from __future__ import annotations

import time
import urllib.parse
from typing import TYPE_CHECKING, Any

from serial.serialutil import (  # type: ignore[attr-defined]  # to_bytes: pyserial's, missing from its stubs
    PortNotOpenError,
    SerialBase,
    SerialException,
    to_bytes,
)

from rig.simulators.device import SimDevice, Unplugged
from rig.simulators.urlhandler import registry
from rig.simulators.urlhandler.registry import RigConflict
from rig.simulators.world import SimWorld

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

DEVICES = ("cannon", "gates", "clamp")
OPTIONS = ("scene", "rig")


def parse_url(url: str) -> tuple[str, str, str]:
    """(device, scene, rig) of a sim:// URL; ValueError naming what is wrong."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "sim":
        raise ValueError(f"expected sim://<device>?scene=...&rig=..., got {url!r}")
    device = parts.netloc.lower()
    if device not in DEVICES:
        raise ValueError(f"sim:// device must be one of {', '.join(DEVICES)}, got {device!r}")
    query = urllib.parse.parse_qs(parts.query, keep_blank_values=True)
    unknown = sorted(set(query) - set(OPTIONS))
    if unknown:
        raise ValueError(f"unknown sim:// option(s) {', '.join(unknown)}; known: {', '.join(OPTIONS)}")
    scene = query.get("scene", [registry.DEFAULT_SCENE])[-1] or registry.DEFAULT_SCENE
    rig = query.get("rig", [registry.DEFAULT_RIG])[-1] or registry.DEFAULT_RIG
    return device, scene, rig


class Serial(SerialBase):
    """A serial port onto a simulated device."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:  # SerialBase's arguments, passed on
        self._device: SimDevice | None = None
        self._world: SimWorld | None = None
        self._key: tuple[str, str] | None = None
        self._cancel = False
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        """Attach to the device of the URL's rig (building its world on first use)."""
        if self.is_open:
            raise SerialException("Port is already open.")
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        try:
            name, scene, rig = parse_url(self.port)
        except ValueError as exc:
            raise SerialException(str(exc)) from None
        try:
            world = registry.world_for(rig, scene)  # a bad scene file raises ConfigError as it is
            registry.claim(rig, name)
        except RigConflict as exc:
            raise SerialException(str(exc)) from None
        self._world, self._device, self._key = world, world.devices[name], (rig, name)
        self._device.replug()  # a fresh open: nothing buffered, and an unplugged device is back
        self.is_open = True

    def close(self) -> None:
        """Detach; wakes a reader blocked in read()."""
        if self.is_open and self._world is not None and self._key is not None:
            self.is_open = False
            registry.release(*self._key)
            with self._world.changed:
                self._world.changed.notify_all()
        super().close()

    def _reconfigure_port(self) -> None:
        """Baud rate and framing mean nothing to a simulated device."""

    def _dev(self) -> tuple[SimWorld, SimDevice]:
        if not self.is_open or self._world is None or self._device is None:
            raise PortNotOpenError()
        return self._world, self._device

    @property
    def in_waiting(self) -> int:
        """Bytes readable now."""
        _, device = self._dev()
        try:
            return device.in_waiting
        except Unplugged:
            raise SerialException("device unplugged") from None

    def read(self, size: int = 1) -> bytes:
        """Up to `size` bytes: what is queued, else whatever comes within the timeout."""
        world, device = self._dev()
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        self._cancel = False
        with world.changed:
            while True:
                try:
                    data = device.read(size)
                except Unplugged:
                    raise SerialException("device unplugged") from None
                if data or size == 0 or not self.is_open or self._cancel:
                    return data
                if deadline is None:
                    world.changed.wait()
                    continue
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return b""
                world.changed.wait(remaining)

    def write(self, data: ReadableBuffer) -> int:
        """Hand bytes to the device; it answers at once."""
        _, device = self._dev()
        try:
            return device.write(to_bytes(data))
        except Unplugged:
            raise SerialException("device unplugged") from None

    def cancel_read(self) -> None:
        """Make a blocked read() return."""
        if self._world is not None:
            with self._world.changed:
                self._cancel = True
                self._world.changed.notify_all()

    def reset_input_buffer(self) -> None:
        """Discard what has already arrived (consequences still in the virtual future stay)."""
        world, device = self._dev()
        with world.lock:
            device.out.discard_due(world.clock)

    def reset_output_buffer(self) -> None:
        """Nothing is ever waiting to go out."""
        self._dev()

    @property
    def out_waiting(self) -> int:
        """Always 0: writes are delivered at once."""
        self._dev()
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        """Clear to send: always."""
        self._dev()
        return True

    @property
    def dsr(self) -> bool:
        """Data set ready: always."""
        self._dev()
        return True

    @property
    def ri(self) -> bool:
        """No ring indicator."""
        self._dev()
        return False

    @property
    def cd(self) -> bool:
        """Carrier detect: always."""
        self._dev()
        return True
