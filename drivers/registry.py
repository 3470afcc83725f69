"""Drivers chosen by configuration: a device's `driver` name becomes an open device.

A name is looked up in this order: the built-in table below (one line per driver), the entry
points of the `bat_rig.drivers` group (a lab's own package: `name = "package.module:factory"`), an
import path `package.module:factory`. A factory takes a `DriverContext` and returns an open device
that satisfies the interface of its kind (rig.core.devices.Cannon, Gates, Clamp or
CompressionTester) and can be
closed. A built-in driver is imported only when a rig names it, so a lab without Modbus needs no
pymodbus loaded.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

from rig.core.config import DEVICE_KINDS, OPTIONAL_KINDS, DeviceSpec, Timeouts
from rig.core.devices import Cannon, Clamp, CompressionTester, Gates
from rig.core.errors import ConfigError, RigError
from rig.drivers.traffic import TrafficRecord

ENTRY_POINT_GROUP = "bat_rig.drivers"


@dataclass(frozen=True)
class Builtin:
    """A built-in driver: the factory of each device kind it drives ("module:attr"), and the simulated
    twin that speaks its wire ("module:class" in rig.simulators; named here, imported only there)."""

    factories: Mapping[str, str]
    twin: str | None = None


# name -> its factories and twin. Adding an instrument class is its module(s) and one line here.
BUILTIN: Mapping[str, Builtin] = {
    "rig-line": Builtin(
        {
            "cannon": "rig.drivers.cannon.driver:CannonDriver.from_context",
            "gates": "rig.drivers.gates.driver:GatesDriver.from_context",
            "clamp": "rig.drivers.clamp.driver:ClampDriver.from_context",
        }
    ),
    "scpi-counter": Builtin(
        {"gates": "rig.drivers.scpi.counter:ScpiCounterGates.from_context"},
        twin="rig.simulators.instruments.scpi_counter:ScpiCounterTwin",
    ),
    "vxm-stage": Builtin(
        {"clamp": "rig.drivers.vxm.clamp:VxmClamp.from_context"},
        twin="rig.simulators.instruments.vxm_stage:VxmStageTwin",
    ),
    "modbus-cannon": Builtin(
        {"cannon": "rig.drivers.modbus.cannon:ModbusCannon.from_context"},
        twin="rig.simulators.instruments.modbus_plc:ModbusPlcTwin",
    ),
    "scpi-compression": Builtin(
        {"compression": "rig.drivers.scpi.compression:ScpiCompressionTester.from_context"},
        twin="rig.simulators.instruments.compression_tester:CompressionTesterTwin",
    ),
}

INTERFACES: Mapping[str, type] = {
    "cannon": Cannon,
    "gates": Gates,
    "clamp": Clamp,
    "compression": CompressionTester,
}


@runtime_checkable
class Closable(Protocol):
    """What the session needs of every device besides its interface: close the connection."""

    def close(self) -> None: ...


@dataclass(frozen=True)
class DriverContext:
    """What a driver's factory is given: the device, where it is, its options and the rig's timeouts.

    `on_traffic` takes every raw exchange (bytes out 'tx', bytes in 'rx'): the run records them.
    `gate_positions_m` is where the rig config puts the gates (its [gates] positions_m, m from the
    impact point, gate 1 farthest), for a gates driver whose mapping of edges needs it (None: not
    known).
    """

    kind: str
    name: str
    address: str
    options: Mapping[str, Any]
    timeouts: Timeouts = field(default_factory=Timeouts)
    on_traffic: Callable[[TrafficRecord], None] | None = None
    source: str = "rig config"
    gate_positions_m: tuple[float, float, float] | None = None

    def refuse(self, message: str) -> ConfigError:
        """A configuration error naming the device's [devices] table."""
        return ConfigError(f"[devices.{self.kind}] {message}", source=self.source)

    def only_options(self, known: Mapping[str, type | tuple[type, ...]]) -> dict[str, Any]:
        """The options, checked against the names and types the driver knows; one line for a stranger."""
        unknown = sorted(set(self.options) - set(known))
        if unknown:
            names = ", ".join(sorted(known)) or "none"
            raise self.refuse(f"driver does not know option {unknown[0]!r} (it takes: {names})")
        for key, value in self.options.items():
            expected = known[key]
            if isinstance(value, bool) and bool not in (
                expected if isinstance(expected, tuple) else (expected,)
            ):
                raise self.refuse(f"option {key!r} must be {_type_names(expected)}, not a flag")
            if not isinstance(value, expected):
                raise self.refuse(f"option {key!r} must be {_type_names(expected)}, not {value!r}")
        return dict(self.options)


def _type_names(expected: type | tuple[type, ...]) -> str:
    kinds = expected if isinstance(expected, tuple) else (expected,)
    return " or ".join(
        {int: "a whole number", float: "a number", str: "text", bool: "true or false"}.get(k, k.__name__)
        for k in kinds
    )


def known_drivers(kind: str) -> list[str]:
    """The names a rig config can give for device `kind`: built in, then installed entry points."""
    names = [name for name, entry in BUILTIN.items() if kind in entry.factories]
    return names + sorted(ep.name for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in BUILTIN)


def factory_for(kind: str, spec: DeviceSpec, source: str = "rig config") -> Callable[[DriverContext], Any]:
    """The factory `spec.driver` names for device `kind`; ConfigError (one line) if there is none."""
    if kind not in (*DEVICE_KINDS, *OPTIONAL_KINDS):
        kinds = ", ".join((*DEVICE_KINDS, *OPTIONAL_KINDS))
        raise ConfigError(f"no device kind {kind!r} (kinds: {kinds})", source=source)
    name = spec.driver
    found = [ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name == name]
    if found and name in BUILTIN:
        raise ConfigError(
            f"[devices.{kind}] driver {name!r} is built in, and also the entry point {found[0].value!r}: "
            "rename the package's entry point",
            source=source,
        )
    if name in BUILTIN:
        target = BUILTIN[name].factories.get(kind)
        if target is None:
            serves = ", ".join(BUILTIN[name].factories)
            raise ConfigError(
                f"[devices.{kind}] driver {name!r} drives the {serves}, not the {kind}", source=source
            )
        return _load(target, kind, name, source)
    if len({ep.value for ep in found}) > 1:
        where = ", ".join(sorted({ep.value for ep in found}))
        raise ConfigError(
            f"[devices.{kind}] driver {name!r} is named by more than one package: {where}", source=source
        )
    if found:
        return _load(found[0].value, kind, name, source)
    if ":" in name:
        return _load(name, kind, name, source)
    raise ConfigError(
        f"[devices.{kind}] no driver {name!r} (known: {', '.join(known_drivers(kind))}; "
        "or an import path package.module:factory)",
        source=source,
    )


def _load(target: str, kind: str, name: str, source: str) -> Callable[[DriverContext], Any]:
    """The factory `target` ("package.module:attr.attr") names; every failure one ConfigError line."""
    module_name, _, attr = target.partition(":")

    def refused(why: str) -> ConfigError:
        return ConfigError(f"[devices.{kind}] driver {name!r}: {why}", source=source)

    if not module_name or module_name.startswith("."):
        raise refused(f"{target!r} is not package.module:factory")
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise refused(f"cannot import {module_name!r}: {exc}") from None
    except Exception as exc:  # a lab's module that fails as it loads, whatever it raises
        raise refused(f"importing {module_name!r} failed: {type(exc).__name__}: {exc}") from None
    for part in attr.split(".") if attr else ():
        if not hasattr(obj, part):
            raise refused(f"{module_name!r} has no {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise refused(f"{target!r} is not a factory")
    factory: Callable[[DriverContext], Any] = obj
    return factory


def open_device(kind: str, context: DriverContext, spec: DeviceSpec) -> Any:
    """Build and open device `kind` with its configured driver; the result is checked against the
    kind's interface (a driver that lacks a method is refused, and closed, before any run uses it)."""
    factory = factory_for(kind, spec, context.source)
    try:
        device = factory(context)
    except (RigError, OSError):
        raise  # ours and the system's name their cause already
    except Exception as exc:  # a lab's factory that fails otherwise: one line, not a traceback
        raise context.refuse(f"driver {spec.driver!r} failed to open: {type(exc).__name__}: {exc}") from None
    missing = [m for m in [*_methods(INTERFACES[kind]), "close"] if not callable(getattr(device, m, None))]
    if missing:
        if isinstance(device, Closable):
            device.close()
        raise ConfigError(
            f"[devices.{kind}] driver {spec.driver!r} gives a {type(device).__name__} that lacks "
            + ", ".join(missing)
            + f" (a {kind} needs rig.core.devices.{INTERFACES[kind].__name__})",
            source=context.source,
        )
    return device


def _methods(interface: type) -> list[str]:
    return sorted(
        name for name in vars(interface) if not name.startswith("_") and callable(getattr(interface, name))
    )
