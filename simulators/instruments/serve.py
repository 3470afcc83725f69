"""Serve one simulated rig through real-instrument twins (`rig sim serve --instruments`).

Each device of one SimWorld is served by the twin of an instrument class at its own wire level on a
TCP port of 127.0.0.1: the gates by a SCPI counter, the clamp by a VXM stage and its swing sensor,
the cannon by a Modbus PLC; a scene whose barrel rolling softens (composite) also has its
barrel-compression tester served (rig.simulators.instruments.compression_tester). The rig config
that names their drivers (and marks each device simulated) is printed as `<device> <driver>
<address>` lines and, if asked, written as a TOML file that `rig certify --config` reads.
"""

from __future__ import annotations

import importlib
import threading
from collections.abc import Mapping
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any, Protocol, TextIO

from rig.core.config import DEVICE_KINDS
from rig.core.errors import ConfigError
from rig.core.tomlfile import dump_toml
from rig.drivers.registry import BUILTIN
from rig.simulators.register import sample_register
from rig.simulators.scene import Scene
from rig.simulators.warmup import warm_up
from rig.simulators.world import SimWorld

PORTS = 1  # ports a twin takes unless its class says otherwise (the stage and its sensor: 2)
BREAK_IN_DRIVER = "scpi-compression"  # the barrel-compression tester served beside a softening barrel


class Twin(Protocol):
    """What serving needs of an instrument twin."""

    DRIVER: str
    KIND: str

    def start(self, host: str = "127.0.0.1", port: int = 0) -> str: ...
    def device_table(self) -> dict[str, Any]: ...
    def close(self) -> None: ...


def twin_drivers(chosen: Mapping[str, str] | None = None) -> dict[str, str]:
    """Device kind -> the driver whose twin serves it: the chosen one (kind -> driver name), else
    the first built-in driver of that kind that has a twin. ConfigError (one line) for a kind or a
    driver that cannot be served, or a kind left without a twin."""
    chosen = dict(chosen or {})
    for kind, name in chosen.items():
        if kind not in DEVICE_KINDS:
            raise ConfigError(
                f"--twin {kind}={name}: no device kind {kind!r} (kinds: {', '.join(DEVICE_KINDS)})"
            )
        if name not in _with_twins(kind):
            served = ", ".join(_with_twins(kind)) or "none"
            raise ConfigError(
                f"--twin {kind}={name}: no twin of driver {name!r} for the {kind} (twins: {served})"
            )
    drivers: dict[str, str] = {}
    for kind in DEVICE_KINDS:
        found = chosen.get(kind) or next(iter(_with_twins(kind)), None)
        if found is None:
            raise ConfigError(f"no instrument twin for the {kind}")
        drivers[kind] = found
    return drivers


def _with_twins(kind: str) -> list[str]:
    """The built-in drivers of device `kind` that have a twin, in the registry's order."""
    return [name for name, entry in BUILTIN.items() if entry.twin is not None and kind in entry.factories]


def twin_class(driver: str) -> type[Any]:
    """The twin class of built-in `driver` (its registry line names it)."""
    target = BUILTIN[driver].twin
    if target is None:
        raise ConfigError(f"driver {driver!r} has no simulated twin")
    module, _, name = target.partition(":")
    cls: type[Any] = getattr(importlib.import_module(module), name)
    return cls


def start_twins(
    world: SimWorld,
    host: str = "127.0.0.1",
    base_port: int = 0,
    chosen: Mapping[str, str] | None = None,
    serial: bool = False,
) -> list[Twin]:
    """Start a twin for every device of `world` (`chosen`: kind -> driver, see twin_drivers); with
    `base_port` the twins take consecutive ports from it; with `serial` each twin that has a serial
    form (SERIAL = True: the PLC on Modbus RTU, the stage and sensor) serves it on ptys; stop them
    all if one fails."""
    classes = [twin_class(driver) for driver in twin_drivers(chosen).values()]
    if world.barrel is not None:  # a barrel that rolling softens: the break-in's compression tester too
        classes.append(twin_class(BREAK_IN_DRIVER))
    needed = sum(int(getattr(cls, "PORTS", PORTS)) for cls in classes)
    if base_port and base_port + needed - 1 > 65535:
        raise ConfigError(f"--base-port {base_port}: the twins need {needed} ports from it, past 65535")
    twins: list[Twin] = []
    port = base_port
    try:
        for cls in classes:
            twin = cls(world, serial=True) if serial and getattr(cls, "SERIAL", False) else cls(world)
            twins.append(twin)
            twin.start(host, port)
            if base_port:
                port += int(getattr(cls, "PORTS", PORTS))
    except BaseException:
        for twin in twins:
            twin.close()
        raise
    return twins


def rig_config(scene: Scene, twins: list[Twin]) -> dict[str, Any]:
    """The rig config that runs `scene` through `twins`: their drivers, addresses and options, the
    scene's gate positions and aim table; the rig is named sim-<scene>-instruments. With the
    barrel-compression tester (an accelerated break-in's), the sample equipment register too: an ABI
    run needs its barrel-compression-tester role (rig.simulators.register)."""
    config: dict[str, Any] = {
        "name": f"simulated rig through instrument twins ({scene.name})",
        "identity": {"name": f"sim-{scene.name}-instruments"},
        "devices": {twin.KIND: twin.device_table() for twin in twins},
        **scene.rig_config_fragment(),
    }
    if "compression" in config["devices"]:
        register = sample_register(datetime.now(UTC).date())  # dates as TOML text: YYYY-MM-DD
        config["equipment"] = [
            {k: str(v) if isinstance(v, date) else v for k, v in item.items()} for item in register
        ]
    return config


def serve_instruments(
    scene: Scene,
    *,
    host: str = "127.0.0.1",
    base_port: int = 0,
    write_config: Path | None = None,
    stop: threading.Event | None = None,
    out: TextIO | None = None,
    warm: bool = True,
    chosen: Mapping[str, str] | None = None,
    serial: bool = False,
) -> None:
    """Serve `scene` through the twins (`chosen`: kind -> driver; `serial`: on ptys where a twin
    can) until interrupted or `stop` is set."""
    import sys

    out = out if out is not None else sys.stdout
    stop = stop if stop is not None else threading.Event()
    if warm:
        warm_up(scene)
    world = SimWorld(scene)
    twins = start_twins(world, host, base_port, chosen, serial)
    try:
        config = rig_config(scene, twins)
        for kind, table in config["devices"].items():
            print(f"{kind} {table['driver']} {table['address']}", file=out, flush=True)
        if write_config is not None:
            write_config.write_text(dump_toml(config), encoding="utf-8")
            print(f"rig config: {write_config}", file=out, flush=True)
        while not stop.wait(0.2):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        for twin in twins:
            twin.close()
