"""pyserial URL scheme sim://<cannon|gates|clamp>?scene=<name|path>&rig=<name> (in-process sim).

Call `register()` once, then `serial.serial_for_url("sim://gates?scene=lab")` opens the gates
of the simulated rig "default"; ports opened with the same `rig` share one SimWorld.
"""

from __future__ import annotations

from rig.simulators.urlhandler.registry import drop_world, get_world, install_world, reset_worlds

PACKAGE = __name__


def register() -> None:
    """Let serial.serial_for_url resolve sim:// URLs (idempotent)."""
    import serial

    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)


__all__ = ["drop_world", "get_world", "install_world", "register", "reset_worlds"]
