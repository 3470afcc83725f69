"""The rig's configuration (pydantic, loadable from TOML): ports, geometry, aiming, timeouts."""

from __future__ import annotations

import re
import socket
from collections.abc import Mapping
from datetime import date
from pathlib import Path
from typing import Annotated, Any, Literal
from urllib.parse import parse_qs, urlsplit

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from rig.core.errors import ConfigError
from rig.core.tomlfile import read_toml, validate


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


DEVICE_KINDS = ("cannon", "gates", "clamp")
# devices a rig may have besides: a procedure that needs one says so (the ABI: a compression tester)
OPTIONAL_KINDS = ("compression",)
Address = Annotated[str, Field(min_length=1, max_length=1024)]


class Ports(_Model):
    """Port URL of each device: a device path, socket://host:port, sim://..., spy://...

    The short form for the rig's own line protocol: a device given here and not in [devices]
    uses the `rig-line` driver at this URL.
    """

    cannon: Address | None = None
    gates: Address | None = None
    clamp: Address | None = None


# A driver's option: a number, a flag, a text or a short list or table of them (a register map).
OptionValue = str | int | float | bool | list[str | int | float | bool] | dict[str, str | int | float | bool]


class DeviceSpec(_Model):
    """One device's driver and its own options ([devices.cannon] etc.).

    `driver` is a registered name (`rig-line`, `scpi-counter`, `vxm-stage`, `modbus-cannon`), the
    name of an entry point in the `bat_rig.drivers` group (a lab's own package), or an import path
    `package.module:factory`. `address` is what the driver connects to (a port URL, a VISA
    resource, host:port); `options` are the driver's own (it refuses any it does not know).
    """

    driver: Annotated[str, Field(min_length=1, max_length=256)] = "rig-line"
    address: Address | None = None
    options: dict[Annotated[str, Field(max_length=64)], OptionValue] = Field(
        default_factory=dict, max_length=200
    )
    simulated: bool = False  # a simulated twin (rig sim serve --instruments writes it): no bat is measured

    @property
    def is_simulated(self) -> bool:
        """Marked simulated, or at a sim:// address (simulated_device)."""
        return simulated_device(self.address, self.simulated)


def simulated_device(address: object, marked: object = False) -> bool:
    """The one rule for a simulated device: marked so (an instrument twin), or at a sim:// address."""
    return marked is True or (isinstance(address, str) and address.startswith("sim://"))


def recorded_rig_simulated(rig: Mapping[str, Any]) -> bool:
    """RigConfig.simulated of a rig config as a run recorded it (a JSON mapping, read leniently)."""
    ports, devices = _table(rig, "ports"), _table(rig, "devices")
    for kind in DEVICE_KINDS:
        table = _table(devices, kind)
        if simulated_device(table.get("address") or ports.get(kind), table.get("simulated")):
            return True
    return False


def _table(data: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    """data[key] if it is a table, else an empty one."""
    found = data.get(key)
    return found if isinstance(found, dict) else {}


class Devices(_Model):
    """Each device's driver; a device left out uses `rig-line` at its [ports] URL."""

    cannon: DeviceSpec | None = None
    gates: DeviceSpec | None = None
    clamp: DeviceSpec | None = None
    compression: DeviceSpec | None = None  # a barrel-compression tester (optional: the ABI needs one)


# A cannon rig is a few metres long (muzzle to bat about 1.5-3 m): no gate sits farther than 5 m
# from the impact point. The nearest gate must be clear of the bat and of the ball in contact: a
# ball's diameter (74 mm) plus a barrel's radius (33 mm), about 0.1 m. Gates closer than 20 mm
# apart time a ball at 80 m/s over less than 250 us.
RIG_LENGTH_M = 5.0
NEAREST_GATE_M = 0.1
MIN_GATE_GAP_M = 0.02


class GateGeometry(_Model):
    """Gate distances from the impact point along the ball path, farthest (gate 1) first, m."""

    positions_m: tuple[float, float, float] = Field(
        (0.75, 0.50, 0.25), description="m, falling, within 0.1-5 m of the impact point, >= 20 mm apart"
    )
    # A gate placed no better than 2 cm (8 % of a 0.25 m spacing) cannot support a certificate.
    position_uncertainty_m: Annotated[float, Field(ge=0.0, le=0.02)] = 0.000127  # +-0.005 in

    @field_validator("positions_m")
    @classmethod
    def _farthest_first(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if not v[0] > v[1] > v[2] >= 0.0:
            raise ValueError("gate positions must be decreasing (gate 1 farthest) and >= 0")
        if v[0] > RIG_LENGTH_M:
            raise ValueError(f"gate 1 at {v[0]:g} m is beyond a rig's {RIG_LENGTH_M:g} m")
        if v[2] < NEAREST_GATE_M:
            raise ValueError(f"gate 3 at {v[2]:g} m is in the bat's way: at least {NEAREST_GATE_M:g} m")
        if min(v[0] - v[1], v[1] - v[2]) < MIN_GATE_GAP_M:
            raise ValueError(f"gates must be at least {MIN_GATE_GAP_M * 1000:g} mm apart")
        return v


class AimCalibration(_Model):
    """Exit speed against tank pressure, from calibration shots; aiming inverts it."""

    # A tank of at most 20 bar, a ball at most 100 m/s (224 mph), at most 100 calibration points.
    pressure_kpa: tuple[Annotated[float, Field(gt=0.0, le=2000.0)], ...] = Field(
        (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 800.0), max_length=100
    )
    speed_m_s: tuple[Annotated[float, Field(gt=0.0, le=100.0)], ...] = Field(
        (37.4, 49.6, 56.9, 61.3, 64.2, 66.0, 68.0), max_length=100
    )

    @model_validator(mode="after")
    def _monotone(self) -> AimCalibration:
        p, v = np.asarray(self.pressure_kpa), np.asarray(self.speed_m_s)
        if p.size != v.size or p.size < 2:
            raise ValueError("pressure_kpa and speed_m_s need the same length, at least 2")
        if np.any(np.diff(p) <= 0) or np.any(np.diff(v) <= 0):
            raise ValueError("pressure and speed must both increase strictly")
        return self

    def pressure_for(self, speed_m_s: float) -> float:
        """Pressure expected to give `speed_m_s` (linear interpolation; refuses extrapolation)."""
        if not self.speed_m_s[0] <= speed_m_s <= self.speed_m_s[-1]:
            raise ConfigError(
                f"speed {speed_m_s:g} m/s is outside the aim calibration "
                f"({self.speed_m_s[0]:g}-{self.speed_m_s[-1]:g} m/s)"
            )
        return float(np.interp(speed_m_s, self.speed_m_s, self.pressure_kpa))


class Timeouts(_Model):
    """How long the controller waits, s. Every wait has a deadline, of seconds to minutes."""

    # a device answers in ms; 50 ms carries a 32-byte reply at 9600 baud
    reply_s: Annotated[float, Field(ge=0.05, le=60.0)] = 1.0
    pressure_ready_s: Annotated[float, Field(ge=1.0, le=1800.0)] = 120.0  # a fill: 1 s to 30 min
    stage_s: Annotated[float, Field(ge=1.0, le=600.0)] = 30.0  # a stage crosses the bat: 1 s to 10 min
    # silence that ends a shot's gate events: >= 0.1 s, the time a slow (8 m/s) rebound needs to
    # clear 0.75 m of gates
    shot_window_s: Annotated[float, Field(ge=0.1, le=60.0)] = 0.5
    recoil_s: Annotated[float, Field(gt=0.0, le=60.0)] = 0.02  # the encoder reports within ms of the impact,
    # long before the rebound has cleared the far gate, so little waiting is left by then


class Air(_Model):
    """The ball's drag and the lab air's pressure: inputs of the drag correction (docs/measurement.md 3.6).

    Cd of a baseball near the inbound 60 m/s (0.35 +- 0.05) and in the subcritical flow of the
    ~11 m/s rebound (0.5 +- 0.1): see docs/measurement.md for the sources. 0 means no drag (a
    simulated ideal rig). The ENV reading gives temperature and humidity; the pressure is stated.
    """

    drag_coefficient: Annotated[float, Field(ge=0.0, le=1.5)] = 0.35
    drag_coefficient_u: Annotated[float, Field(ge=0.0, le=1.0)] = 0.05
    rebound_drag_coefficient: Annotated[float, Field(ge=0.0, le=1.5)] = 0.5
    rebound_drag_coefficient_u: Annotated[float, Field(ge=0.0, le=1.0)] = 0.1
    ball_diameter_m: Annotated[float, Field(gt=0.05, lt=0.12)] = 0.0737  # 2.9 in
    pressure_kpa: Annotated[float, Field(ge=50.0, le=110.0)] = 101.325  # standard atmosphere
    pressure_u_kpa: Annotated[float, Field(ge=0.0, le=20.0)] = 3.0  # [assumed] weather at sea level
    temperature_u_c: Annotated[float, Field(ge=0.0, le=10.0)] = 0.5  # [assumed] ENV sensor
    humidity_u_pct: Annotated[float, Field(ge=0.0, le=50.0)] = 5.0  # [assumed] ENV sensor


class Pendulum(_Model):
    """The MOI pendulum's own inputs (ASTM F2398): local g, timer, scale, balance point, amplitude."""

    gravity_m_s2: Annotated[float, Field(ge=9.7, le=9.9)] = 9.80665  # standard g; set the lab's
    gravity_u_m_s2: Annotated[float, Field(ge=0.0, le=0.1)] = 0.015  # covers 9.78-9.83 m/s^2
    timer_resolution_s: Annotated[float, Field(gt=0.0, le=0.01)] = 1e-6  # [assumed] period timer
    scale_resolution_kg: Annotated[float, Field(gt=0.0, le=0.05)] = 0.001  # [assumed] 1 g scale
    balance_point_u_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0008  # [assumed] +-1/32 in
    amplitude_u_deg: Annotated[float, Field(ge=0.0, le=10.0)] = 0.5  # [assumed] release angle


class Model(_Model):
    """The collision model's calibration for this rig's cross-check (rig model calibrate)."""

    calibration: Annotated[str, Field(min_length=1, max_length=4096)] | None = None  # relative to the file
    # who named it: the rig config file, or `rig certify --calibration` / rig.certify(calibration=)
    named_by: Literal["rig config", "command line", "script"] = "rig config"


# What an item of the equipment register is for: the three devices, then the instruments a
# result depends on besides them (rig.instruments.roles_for says which a procedure needs).
EQUIPMENT_ROLES: dict[str, str] = {
    "cannon": "the air cannon (its pressure sets the inbound speed)",
    "gates": "the light gates and their counter (ball speeds)",
    "clamp": "the pivot clamp (impact point; the MOI pendulum's swing)",
    "gate-gauge": "the tool the gate positions are measured with",
    "pendulum-timer": "the MOI pendulum's period timer",
    "scale": "the scale bats and balls are weighed on",
    "thermometer": "the lab's air temperature",
    "hygrometer": "the lab's relative humidity",
    "barometer": "the lab's air pressure (the drag correction)",
    "compression-tester": "the ball compression tester (ASTM F1888, the ball lot's qualification)",
    "barrel-compression-tester": "the barrel-compression tester (accelerated break-in, at a fixed squeeze)",
}
Role = Literal[
    "cannon",
    "gates",
    "clamp",
    "gate-gauge",
    "pendulum-timer",
    "scale",
    "thermometer",
    "hygrometer",
    "barometer",
    "compression-tester",
    "barrel-compression-tester",
]


class Equipment(_Model):
    """One item of the rig's equipment list: what it is, its serial number and its calibration.

    `device` ties it to a device of the rig (its identity's serial number must then match);
    other items (a scale, a thermometer, a gauge block) leave it out. `role` says what the item is
    for (EQUIPMENT_ROLES; a device's item has its device's role). A run refuses an item past its
    `due` date unless an override (who, why) is recorded.
    """

    name: Annotated[str, Field(min_length=1, max_length=120)]
    device: Literal["cannon", "gates", "clamp"] | None = None
    role: Role | None = None
    serial: Annotated[str, Field(min_length=1, max_length=64)] | None = None
    certificate: Annotated[str, Field(min_length=1, max_length=120)] | None = None
    calibrated: date | None = None
    due: date | None = None

    @model_validator(mode="after")
    def _due_after_calibration(self) -> Equipment:
        if self.calibrated is not None and self.due is not None and self.due < self.calibrated:
            raise ValueError(f"{self.name}: due {self.due} is before its calibration {self.calibrated}")
        if self.device is not None and self.role is not None and self.role != self.device:
            raise ValueError(f"{self.name}: role {self.role!r} is not its device's ({self.device!r})")
        return self

    @property
    def purpose(self) -> str | None:
        """The item's role: its own, else its device's; None for an item of neither."""
        return self.role or self.device


RIG_NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}"  # also a key file's name: no path separators
_NOT_NAME = re.compile(r"[^A-Za-z0-9._-]+")


class Console(_Model):
    """How the console takes the operator's answers.

    `one_key`: Enter on a shot's review also passes the ring check after it, and Enter on that check
    the one before the next shot (nothing touches the bat between). Off by default: each inspection
    is asked on its own prompt. On, the record says of each such answer that it came with the other
    one, not that it was inspected (rig.core.events.OperatorAnswered.given).
    """

    one_key: Annotated[bool, Field(strict=True)] = False


class Identity(_Model):
    """Which rig this is, as each run records it: name (default sim-SCENE or the host name), serial."""

    name: Annotated[str, Field(pattern=f"^{RIG_NAME_PATTERN}$")] | None = None
    serial: Annotated[str, Field(min_length=1, max_length=64)] | None = None
    # the lab identity file (rig.core.lab) its reports name, relative to the rig config
    lab: Annotated[str, Field(min_length=1, max_length=500)] | None = None


def rig_name(text: str) -> str:
    """`text` made a valid rig name (other characters become '-'); 'rig' if nothing is left."""
    cleaned = _NOT_NAME.sub("-", text).strip("-._")[:64]
    return cleaned or "rig"


def _sim_scene(addresses: dict[str, str]) -> str | None:
    """The scene of a fully simulated rig (sim:// on every port), else None."""
    scenes = set()
    for url in addresses.values():
        if not url.startswith("sim://"):
            return None
        scenes.add(parse_qs(urlsplit(url).query).get("scene", ["ideal"])[0])
    scene = scenes.pop() if len(scenes) == 1 else "mixed"
    return Path(scene).stem if scene.endswith(".toml") else scene


class RigConfig(_Model):
    """Everything the controller must know about one rig."""

    name: str = "rig"
    ports: Ports = Ports()
    devices: Devices = Devices()
    gates: GateGeometry = GateGeometry()
    aim: AimCalibration = AimCalibration()
    timeouts: Timeouts = Timeouts()
    impact_from_pivot_m: Annotated[float, Field(gt=0.1, lt=0.9)] = 0.56
    cannon_cycle_s: Annotated[float, Field(ge=1.0, le=3600.0)] = 45.0  # refill and reload between shots
    # [assumed]; 1 s to an hour
    air: Air = Air()
    pendulum: Pendulum = Pendulum()
    model: Model = Model()
    identity: Identity = Identity()
    console: Console = Console()
    equipment: tuple[Equipment, ...] = Field((), max_length=200)

    @model_validator(mode="after")
    def _every_device_has_an_address(self) -> RigConfig:
        missing = [kind for kind in DEVICE_KINDS if self.device(kind).address is None]
        if missing:
            raise ValueError(
                "no address for " + ", ".join(missing) + ": give it in [ports] or as [devices.<name>] address"
            )
        return self

    def device(self, kind: str) -> DeviceSpec:
        """The driver, address and options of device `kind` ([devices] first, else [ports] with rig-line)."""
        spec: DeviceSpec | None = getattr(self.devices, kind)
        port: str | None = getattr(self.ports, kind, None)
        if spec is None:
            return DeviceSpec(address=port)
        return spec if spec.address is not None else spec.model_copy(update={"address": port})

    def addresses(self) -> dict[str, str]:
        """Each device's address, by kind."""
        return {kind: str(self.device(kind).address) for kind in DEVICE_KINDS}

    @property
    def simulated(self) -> bool:
        """Whether any device of this rig is simulated (a sim:// port or a device marked simulated):
        its runs measure no bat."""
        return any(spec.is_simulated for spec in map(self.device, DEVICE_KINDS))

    def identity_name(self) -> str:
        """The rig's name: [identity] name, else sim-SCENE for a simulated rig, else the host name."""
        if self.identity.name is not None:
            return self.identity.name
        scene = _sim_scene(self.addresses())
        return rig_name(f"sim-{scene}" if scene is not None else socket.gethostname())

    def identity_record(self, software: str) -> dict[str, str | None]:
        """What a run records of the rig: name, serial, software version."""
        return {"name": self.identity_name(), "serial": self.identity.serial, "software": software}

    @classmethod
    def load(cls, path: str | Path) -> RigConfig:
        """Read and validate a TOML file; errors name the file and the field.

        [model] calibration and [identity] lab, when relative, are taken relative to the file.
        """
        config = cls.from_dict(read_toml(path, what="a rig config"), source=str(path))
        named = config.model.calibration
        if named is not None:
            where = str(Path(path).parent / Path(named).expanduser())
            config = config.model_copy(update={"model": Model(calibration=where)})
        lab = config.identity.lab
        if lab is not None:
            where = str(Path(path).parent / Path(lab).expanduser())
            config = config.model_copy(update={"identity": config.identity.model_copy(update={"lab": where})})
        return config

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "config") -> RigConfig:
        """Validate a mapping; errors name the source and the field."""
        return validate(cls, data, source)
