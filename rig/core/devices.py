"""Device records and interfaces: what procedures and the UI know about the rig's devices.

Procedures receive devices through these interfaces (typing.Protocol), never a concrete driver,
so a real driver, a driver on a simulated port or a test fake all fit.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol, runtime_checkable


class CannonState(StrEnum):
    """SAFE -> ARMED -> FIRED -> SAFE; FAULT until RESET."""

    SAFE = "SAFE"
    ARMED = "ARMED"
    FIRED = "FIRED"
    FAULT = "FAULT"


@dataclass(frozen=True)
class Interlocks:
    """Interlock loop: True means closed (safe to fire)."""

    door: bool
    clamp: bool
    estop: bool

    @property
    def all_closed(self) -> bool:
        """True only when every interlock is closed."""
        return self.door and self.clamp and self.estop

    def open_names(self) -> list[str]:
        """Names of the open interlocks."""
        pairs = (("door", self.door), ("clamp", self.clamp), ("estop", self.estop))
        return [name for name, closed in pairs if not closed]


@dataclass(frozen=True)
class CannonStatus:
    """What the cannon reports of itself."""

    state: CannonState
    pressure_kpa: float
    setpoint_kpa: float
    interlocks: Interlocks
    shots: int


@dataclass(frozen=True)
class InstrumentIdentity:
    """What an instrument says it is (the ID command, `*IDN?`, Modbus device identification, the
    stage's model and firmware), recorded at the start of every run."""

    model: str
    firmware: str
    serial_number: str
    maker: str = ""


@runtime_checkable
class Identifiable(Protocol):
    """A device that can say what it is."""

    def identify(self) -> InstrumentIdentity: ...


@dataclass(frozen=True)
class Environment:
    """Lab temperature and relative humidity."""

    temperature_c: float
    humidity_pct: float


@dataclass(frozen=True)
class GateConfig:
    """The gates' counter: number of gates, tick and counter width."""

    gates: int
    tick_ns: float
    bits: int

    @property
    def tick_s(self) -> float:
        """One counter tick in seconds."""
        return self.tick_ns * 1e-9

    @property
    def modulus(self) -> int:
        """The counter wraps at this many ticks."""
        return 1 << self.bits


@dataclass(frozen=True)
class GateCrossing:
    """A beam break: gate (1-based), counter value, and the host's receive time (monotonic s)."""

    gate: int
    tick: int
    host_time_s: float = 0.0


STAGE_RANGE_MM = (100.0, 900.0)  # the clamp stage: impact point from the pivot, the one statement of it


@dataclass(frozen=True)
class ClampStatus:
    """What the pivot clamp reports of itself."""

    locked: bool
    position_mm: float
    moving: bool
    angle_deg: float


@dataclass(frozen=True)
class PendulumPeriod:
    """Mean pendulum period over `cycles` swings from amplitude `amplitude_deg`."""

    period_s: float
    amplitude_deg: float
    cycles: int
    u_s: float | None = None  # its standard uncertainty, when the host computed it from sampled angles


@dataclass(frozen=True)
class Recoil:
    """The bat's peak angular speed about the pivot just after an impact, rad/s."""

    omega_rad_s: float


@runtime_checkable
class Cannon(Protocol):
    """An air cannon that fires only when armed with every interlock closed."""

    def status(self) -> CannonStatus: ...
    def set_pressure(self, kpa: float, wait_ready: bool = True) -> None: ...
    def arm(self) -> None: ...
    def fire(self) -> int: ...
    def vent(self) -> None: ...
    def reset(self) -> None: ...
    def environment(self) -> Environment: ...


@runtime_checkable
class BallLoader(Protocol):
    """A cannon told which ball is in its breech (LOAD), so its record names the ball of each shot."""

    def load_ball(self, ball_id: str) -> None: ...


@runtime_checkable
class FireAware(Protocol):
    """A device told that the cannon is about to fire (optional, like BallLoader).

    `before_fire()` is called once per shot in the fire path (rig.protocols.shot.fire_shot), after
    the tank has reached its pressure and before the interlocks are read and FIRE is written: the
    last moment before the shot that does not come between the interlock read and FIRE. A clamp
    whose sensor captures on its own (rig.drivers.vxm) sets aside there what it captured before
    the shot (an operator touching the bat after the stage moved), so the shot's recoil is only
    the shot's.
    """

    def before_fire(self) -> None: ...


@runtime_checkable
class Gates(Protocol):
    """Light gates streaming timestamped beam breaks."""

    def config(self) -> GateConfig: ...
    def arm(self) -> None: ...
    def disarm(self) -> None: ...
    def self_test(self) -> None: ...
    def crossings(self, timeout_s: float) -> Iterator[GateCrossing]: ...


@runtime_checkable
class Clamp(Protocol):
    """Pivot clamp with impact-point stage and angle encoder."""

    def status(self) -> ClampStatus: ...
    def clamp(self) -> None: ...
    def release(self) -> None: ...
    def move_to(self, mm: float) -> None: ...
    def measure_period(self, cycles: int) -> PendulumPeriod: ...
    def next_recoil(self, timeout_s: float) -> Recoil | None: ...


@dataclass(frozen=True)
class BarrelCompression:
    """One barrel-compression reading: the load cell's force with the anvils at a fixed displacement."""

    force_lbf: float
    displacement_in: float

    @property
    def stiffness_lbf_per_in(self) -> float:
        """Force over displacement: the barrel's diametral stiffness at the tested location."""
        return self.force_lbf / self.displacement_in


@runtime_checkable
class CompressionTester(Protocol):
    """A barrel-compression tester: squeezes the barrel to its fixed displacement, reads the force."""

    def measure_compression(self) -> BarrelCompression: ...
