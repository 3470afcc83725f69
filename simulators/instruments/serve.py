"""Serve one simulated rig through real-instrument twins (`rig sim serve --instruments`).

Each device of one SimWorld is served by the twin of an instrument class at its own wire level on a
TCP port of 127.0.0.1: the gates by a SCPI counter, the clamp by a VXM stage and its swing sensor,
the cannon by a Modbus PLC. The rig config that names the three drivers (and marks each device
simulated) is printed as `<device> <driver> <address>` lines and, if asked, written as a TOML file
that `rig certify --config` reads.
"""

from __future__ import annotations

import importlib
import threading
from pathlib import Path
from typing import Any, Protocol, TextIO

from rig.core.errors import ConfigError
from rig.core.tomlfile import dump_toml
from rig.simulators.scene import Scene
from rig.simulators.warmup import warm_up
from rig.simulators.world import SimWorld

# device -> the twin that serves it ("module:class"); a device without one is not served this way
TWINS = {
    "cannon": "rig.simulators.instruments.modbus_plc:ModbusPlcTwin",
    "gates": "rig.simulators.instruments.scpi_counter:ScpiCounterTwin",
    "clamp": "rig.simulators.instruments.vxm_stage:VxmStageTwin",
}
PORTS_PER_TWIN = 2  # the stage and its sensor take two; the others one


class Twin(Protocol):
    """What serving needs of an instrument twin."""

    DRIVER: str
    KIND: str

    def start(self, host: str = "127.0.0.1", port: int = 0) -> str: ...
    def device_table(self) -> dict[str, Any]: ...
    def close(self) -> None: ...


def twin_class(kind: str) -> type[Any] | None:
    """The twin class of device `kind`, None if it has none (yet)."""
    module, _, name = TWINS[kind].partition(":")
    try:
        cls: type[Any] = getattr(importlib.import_module(module), name)
        return cls
    except ModuleNotFoundError:
        return None


def start_twins(world: SimWorld, host: str = "127.0.0.1", base_port: int = 0) -> list[Twin]:
    """Start a twin for every device of `world` that has one; stop them all if one fails."""
    twins: list[Twin] = []
    try:
        for i, kind in enumerate(TWINS):
            cls = twin_class(kind)
            if cls is None:
                raise ConfigError(f"no instrument twin for the {kind} ({TWINS[kind]} is missing)")
            twin = cls(world)
            twins.append(twin)
            twin.start(host, base_port + PORTS_PER_TWIN * i if base_port else 0)
    except BaseException:
        for twin in twins:
            twin.close()
        raise
    return twins


def rig_config(scene: Scene, twins: list[Twin]) -> dict[str, Any]:
    """The rig config that runs `scene` through `twins`: their drivers, addresses and options, the
    scene's gate positions and aim table; the rig is named sim-<scene>-instruments."""
    return {
        "name": f"simulated rig through instrument twins ({scene.name})",
        "identity": {"name": f"sim-{scene.name}-instruments"},
        "devices": {twin.KIND: twin.device_table() for twin in twins},
        **scene.rig_config_fragment(),
    }


def serve_instruments(
    scene: Scene,
    *,
    host: str = "127.0.0.1",
    base_port: int = 0,
    write_config: Path | None = None,
    stop: threading.Event | None = None,
    out: TextIO | None = None,
    warm: bool = True,
) -> None:
    """Serve `scene` through the three twins until interrupted or `stop` is set."""
    import sys

    out = out if out is not None else sys.stdout
    stop = stop if stop is not None else threading.Event()
    if warm:
        warm_up(scene)
    world = SimWorld(scene)
    twins = start_twins(world, host, base_port)
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
