"""The console's settings, the rig choices, a run's job, and the device check of the set-up screen.

Every function here that opens ports blocks: the screens call them from thread workers only.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from rig.core.errors import RigError
from rig.measure.registry import BUILTIN_PROCEDURES

if TYPE_CHECKING:  # the session, the drivers and the procedures load when a rig is first used
    from rig.core.bat import BatSpec
    from rig.core.config import RigConfig
    from rig.core.devices import CannonStatus, ClampStatus, Environment, GateConfig
    from rig.protocols.procedure import Procedure
    from rig.request import Prepared

SCENES = ("ideal", "lab", "faulty")
T = TypeVar("T")
# the built-in procedures (protocols/<metric>.toml), named as the metric registry titles them
PROCEDURES = BUILTIN_PROCEDURES
# Held while the console loads the heavy part it left until after the first paint (the session,
# the procedures, the run screen, the report): one thread at a time, so no thread ever sees a
# module another is still initialising (a cycle between two importing threads allows that).
# The light part (the bat model, the renderings) imports without it: the UI thread never waits.
LOADING = threading.RLock()


@dataclass(frozen=True)
class RigChoice:
    """A simulated scene or a rig config file."""

    kind: str  # "sim" | "config"
    ref: str  # scene name or path, config path

    @property
    def label(self) -> str:
        """What the rig selector shows."""
        return f"SIMULATED: {self.ref}" if self.kind == "sim" else f"rig: {self.ref}"

    @property
    def key(self) -> str:
        """A stable id for the selector."""
        return f"{self.kind}:{self.ref}"

    def config(self, bat: BatSpec | None = None, procedure: Procedure | None = None) -> RigConfig:
        """The rig config: a fresh simulated rig (with the bat's true properties, firing the balls
        `procedure` names, aiming as low as its speed), or the file."""
        with LOADING:
            from rig.core.config import RigConfig
            from rig.session import sim_config
        if self.kind == "sim":
            balls = None if procedure is None else procedure.ball.ball_class
            speed = None if procedure is None else procedure.target_speed_m_s
            named = None if procedure is None else procedure.name
            return sim_config(self.ref, bat=bat, ball_class=balls, speed_m_s=speed, balls_of=named)
        return RigConfig.load(self.ref)


@dataclass
class ConsoleSettings:
    """How the console was started (rig tui's options), plus test knobs."""

    db: Path
    rigs: tuple[RigChoice, ...]
    bat_path: str = ""
    procedure: str = "bbcor"
    poll_s: float = 0.5  # how often the cannon is read while the runner waits on the operator
    clock: Callable[[], datetime] | None = None  # the store's clock (tests freeze it)
    device_lock: threading.Lock = field(default_factory=threading.Lock)  # one session at a time

    @classmethod
    def from_args(
        cls, sim: str | None, config: str | None, db: str | Path, bat: str = "", procedure: str = ""
    ) -> ConsoleSettings:
        """Settings for `rig tui --sim [SCENE]` or `rig tui --config RIG.toml`."""
        if config:
            rigs: tuple[RigChoice, ...] = (RigChoice("config", config),)
        else:
            first = sim or "ideal"
            rigs = (RigChoice("sim", first), *(RigChoice("sim", s) for s in SCENES if s != first))
        return cls(Path(db), rigs, bat_path=bat or "", procedure=procedure or "bbcor")


@dataclass(frozen=True)
class RunJob:
    """Everything a certification run needs; `run_id` set to resume one."""

    procedure: Procedure
    bat: BatSpec
    config: RigConfig
    rig_label: str
    run_id: str | None = None
    rig: RigChoice | None = None  # the choice it runs on (a resume command names it)
    prepared: Prepared | None = None  # the set-up's rehearsal of a new run (rig.tui.jobs.prepare_job)


@dataclass(frozen=True)
class LeftOpen:
    """A run the console leaves unfinished (interrupted, stopped by a fault or by quitting)."""

    run_id: str
    reason: str
    rig: RigChoice | None


@dataclass(frozen=True)
class DeviceReport:
    """What the devices said when asked; `errors` names every device that did not answer."""

    cannon: CannonStatus | None = None
    clamp: ClampStatus | None = None
    gates: GateConfig | None = None
    environment: Environment | None = None
    errors: tuple[str, ...] = ()
    checks: tuple[str, bool] | None = None  # the rig's control-chart state, and whether it refuses runs


def read_devices(config: RigConfig, lock: threading.Lock) -> DeviceReport:
    """Open the rig, read every device's status, close it (blocking; skipped while a run holds it)."""
    with LOADING:
        from rig.session import RigSession
    if not lock.acquire(timeout=5.0):
        return DeviceReport(errors=("a run is using the devices",))
    try:
        try:
            session = RigSession.open(config)
        except RigError as exc:
            return DeviceReport(errors=(str(exc),))
        errors: list[str] = []

        def read(what: Callable[[], T]) -> T | None:
            try:
                return what()
            except RigError as exc:
                errors.append(str(exc))
                return None

        with session:
            cannon = read(session.cannon.status)
            clamp = read(session.clamp.status)
            gates = read(session.gates.config)
            environment = read(session.cannon.environment)
        return DeviceReport(cannon, clamp, gates, environment, tuple(errors))
    finally:
        lock.release()


def chart_state(db: Path, config: RigConfig) -> tuple[str, bool]:
    """The rig's control-chart state for the set-up screen (the rig is the one chosen above it), and
    whether it refuses a new run (blocking: reads the store; a store not made yet has no check runs)."""
    rig = config.identity_name()
    if not db.exists():
        return "no check runs yet", False
    with LOADING:
        from rig.quality.records import rig_quality
        from rig.store import Store
    try:
        with Store.open(db, create=False, readonly=True) as store:
            quality = rig_quality(store, rig)
    except RigError as exc:
        return f"control charts not read: {exc}", False
    if quality.unacknowledged:
        _, first = quality.unacknowledged[0]
        more = len(quality.unacknowledged) - 1
        return (
            f"SIGNAL awaiting acknowledgement: {first.describe()}"
            f"{f' (and {more} more)' if more else ''}; certification refused until `rig check ack`",
            True,
        )
    return quality.state(), False
