"""The language between a procedure's plan and the executor that carries it out.

A plan is a generator, in the style of bluesky plans: it yields messages (record this event, ask
the operator, move the stage, fire, evaluate the shot) and receives each message's answer back.
It decides what to do next from the run's folded state (`ctx.state`), which the executor keeps
current, so the same plan starts a run or resumes one. The executor owns what a plan must not
decide for itself: run control (pause, abort), persistence, the devices and their recovery. A dry
run executes the same plan against checking fakes (rig.protocols.dryrun), so it cannot drift from a
real run.

Plans compose with `yield from`: a lab's own procedure is a generator calling the steps in
rig.protocols.steps in its own order (docs/api.md).
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any, TypeVar

from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.events import RunEvent
from rig.core.outcomes import RunVerdict
from rig.core.run_state import RunState
from rig.protocols.procedure import Procedure
from rig.protocols.shot import ShotRecord

T = TypeVar("T")
Plan = Generator["Msg", Any, T]
"""A plan: yields messages, receives their answers, returns its result."""


class Msg:
    """A request from a plan to its executor; each subclass says what the answer is."""


@dataclass(frozen=True)
class Record(Msg):
    """Persist an event (recorded before the plan goes on; committed at its commit point) and fold it
    into the state. -> None"""

    event: RunEvent


@dataclass(frozen=True)
class Checkpoint(Msg):
    """A safe point between shots: the executor honours pause and abort here. -> None"""


@dataclass(frozen=True)
class Ask(Msg):
    """Ask the operator a yes/no question (prompt and answer are recorded). -> bool"""

    prompt_id: str
    text: str


@dataclass(frozen=True)
class Problem(Msg):
    """The procedure cannot be done with this rig or bat: a real run stops (ConfigError), a dry run
    lists it and goes on. -> None"""

    text: str


@dataclass(frozen=True)
class ClearFault(Msg):
    """Reset a cannon fault left by an earlier session (its tank is vented). -> None"""


@dataclass(frozen=True)
class ReadEnvironment(Msg):
    """Read the lab's temperature and humidity. -> rig.core.devices.Environment"""


@dataclass(frozen=True)
class TimePendulum(Msg):
    """Time `cycles` swings of the bat on the pivot. -> rig.core.devices.PendulumPeriod"""

    cycles: int


@dataclass(frozen=True)
class Prepare(Msg):
    """Self-test the gates, lock the bat, put the stage at `location_in` (recorded). -> None"""

    location_in: float


@dataclass(frozen=True)
class Move(Msg):
    """Put the stage at `location_in` unless this session already put it there (recorded). -> None"""

    location_in: float


@dataclass(frozen=True)
class Fire(Msg):
    """Fire the requested shot `index` at `location_in`, aiming for `aim_speed_m_s`.

    The executor records the raw data (ShotFired, traffic) or the loss (ShotLost), and recovers the
    devices after a failure. -> Fired, or None if the shot was lost.
    """

    index: int
    location_in: float
    aim_speed_m_s: float
    ball: str | None = None  # the ball to LOAD first (its id); None: whatever is in the breech


@dataclass(frozen=True)
class Fired:
    """A fired shot's raw record and, if it produced no usable measurement, why."""

    record: ShotRecord
    failure: str = ""


@dataclass(frozen=True)
class Evaluate(Msg):
    """Speeds, metric, uncertainty and validity of a fired shot. -> ShotOutcome"""

    fired: Fired


@dataclass(frozen=True)
class Decide(Msg):
    """The verdict from the valid hits at the chosen location. -> RunVerdict"""


@dataclass(frozen=True)
class MeasureCompression(Msg):
    """Read the barrel-compression tester (accelerated break-in). -> rig.core.devices.BarrelCompression"""


@dataclass(frozen=True)
class AskRolling(Msg):
    """Ask the operator to roll the barrel `passes` passes at `depth_in` (prompt and the reported
    rolling are recorded: OperatorPrompted, BarrelRolled with `stage`). -> rig.protocols.control.Rolling"""

    prompt_id: str
    text: str
    stage: int
    depth_in: float
    passes: int


@dataclass(frozen=True)
class DecideStage(Msg):
    """An accelerated break-in stage's BBCOR from its valid hits (`purpose`), the cross-check at
    `hoop_hz`. -> RunVerdict"""

    purpose: str
    hoop_hz: float | None


@dataclass
class PlanContext:
    """What a plan reads: the procedure, bat and rig as run, the live folded state, the options."""

    procedure: Procedure
    bat: BatSpec
    config: RigConfig
    state: RunState
    who: str = "operator"  # who answers the prompts (recorded with accepted edges and overrules)
    confirm_fire: bool = False  # the operator confirms every shot
    review_shots: bool = False  # the operator may reject a valid shot (never accept an invalid one)
    rig_check: dict[str, str] | None = None  # {who, why}: the rig was checked, budget starts again
    plan_name: str | None = None  # a lab's own plan (module.function), recorded in RunStarted
    options: dict[str, Any] = field(default_factory=dict)  # for a lab's own plans

    def recorded_ball(self) -> dict[str, Any]:
        """The run's ball terms as recorded in RunStarted (before that, as given): {} for none."""
        return dict((self.state.setup or {}).get("ball") or self.options.get("ball") or {})

    def lot_ball_number(self, number: int | None = None) -> int:
        """The run's ball `number` (default: the one in use) as numbered in its lot: counted on from
        the lot's first ball no earlier run has fired (`first_ball`)."""
        n = self.state.ball_number if number is None else number
        return n + int(self.recorded_ball().get("first_ball") or 1) - 1

    def ball_id(self, number: int | None = None) -> str:
        """The id of the run's ball `number` (default: the one in use): the lot's id and its number."""
        recorded = self.recorded_ball()
        lot = str(recorded.get("lot") or "ball")
        width = 3 if int(recorded.get("balls") or 0) >= 100 else 2  # as rig.core.ball.BallLot.ball_id
        return f"{lot}-{self.lot_ball_number(number):0{width}d}"

    def q(self, location_in: float) -> float:
        """The impact point's distance from the pivot (m) for a location from the tip (in)."""
        return self.bat.impact_from_pivot_m(location_in)


PlanFactory = Callable[[PlanContext], "Plan[RunVerdict | None]"]
"""A procedure: builds the plan for a context; its result is the RunFinished payload."""
