"""A ball test as data (TOML, [procedure]): `ccor` on the rigid cylinder, `ball-cor` on the rigid plate.

The built-ins are protocols/ccor.toml, protocols/ball-cor.toml (baseballs) and
protocols/ball-cor-fastpitch.toml (the fastpitch BPF's 47/375 softballs); each value is tagged there as
the bat procedures' are ([C] confirmed, [C2] second hand, [U] unknown: our documented default).
A test fires `balls_per_speed` fresh balls of the lot at each speed, `hits_per_ball` times each,
so the shot schedule (speed, ball, hit) is fixed by the procedure and a resumed run goes on with
the first slot that has no valid hit yet.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, StrictBool, model_validator

from rig.core.ball import BallLot
from rig.core.devices import STAGE_RANGE_MM
from rig.protocols.names import BALL_BUILTIN
from rig.protocols.procedure import Ball, Decision, EnvironmentLimits, Hits, _Model, load_table

BUILTIN_DIR = Path(__file__).parent
CCOR_SPAN_M_S = (25.0, 60.0)  # the speeds a CCOR test must span at least (issue 20)
CCOR_MIN_SPEEDS = 5  # the founding paper's five inbound speeds


class TestTarget(_Model):
    """What the clamp holds for the test, and where the stage puts its face (from the pivot, m)."""

    kind: Literal["cylinder", "plate"]
    diameter_m: Annotated[float, Field(ge=0.005, le=0.5)] | None = None
    impact_from_pivot_m: Annotated[
        float, Field(ge=STAGE_RANGE_MM[0] / 1000.0, le=STAGE_RANGE_MM[1] / 1000.0)
    ] = 0.5

    @property
    def id(self) -> str:
        """The target's id in the store (it is registered as what the clamp holds)."""
        if self.kind == "cylinder":
            return f"TARGET-cylinder-{(self.diameter_m or 0.0) * 1000:g}mm"
        return "TARGET-plate"

    def spec(self) -> dict[str, float | str | None]:
        """What the store records of it."""
        return {"target": self.kind, "diameter_m": self.diameter_m}


class BallProcedure(_Model):
    """A ball test, pinned to the edition it follows."""

    name: str
    test: Literal["ccor", "ball-cor"]
    edition: str
    target: TestTarget
    speeds_m_s: tuple[Annotated[float, Field(gt=10.0, lt=80.0)], ...] = Field(min_length=1, max_length=20)
    speed_tolerance_m_s: Annotated[float, Field(gt=0.0, lt=10.0)] = 0.447  # 1 mph
    balls_per_speed: Annotated[int, Field(ge=1, le=50)] = 6
    hits_per_ball: Annotated[int, Field(ge=1, le=50)] = 1
    hits: Hits = Hits()  # max_reshoots; valid_hits is unused by a ball test
    ball: Ball = Ball()
    environment: EnvironmentLimits = EnvironmentLimits()
    decision: Decision = Decision()
    ring_check: StrictBool = False  # a rigid target has no barrel to deform

    @model_validator(mode="after")
    def _check(self) -> BallProcedure:
        speeds = self.speeds_m_s
        if list(speeds) != sorted(set(speeds)):
            raise ValueError("speeds_m_s must rise strictly")
        if self.test == "ccor":
            if self.target.kind != "cylinder":
                raise ValueError("a ccor test is on the rigid cylinder (target.kind = 'cylinder')")
            if self.target.diameter_m is None:
                raise ValueError("the cylinder target needs diameter_m")
            if len(speeds) < CCOR_MIN_SPEEDS:
                raise ValueError(f"a ccor test needs at least {CCOR_MIN_SPEEDS} speeds, not {len(speeds)}")
            lo, hi = CCOR_SPAN_M_S
            if speeds[0] > lo or speeds[-1] < hi:
                raise ValueError(f"the ccor speeds must span at least {lo:g}-{hi:g} m/s")
        else:
            if self.target.kind != "plate":
                raise ValueError("a ball-cor test is on the rigid plate (target.kind = 'plate')")
            if len(speeds) != 1:
                raise ValueError("a ball-cor test has one speed (ASTM F1887: 60 mph = 26.8 m/s)")
            if self.hits_per_ball < 2:
                raise ValueError(
                    "hits_per_ball must be at least 2: the wear per hit is measured within a ball"
                )
        if self.balls_needed > 999:
            raise ValueError(f"the test needs {self.balls_needed} balls; at most 999")
        return self

    @property
    def balls_needed(self) -> int:
        """How many balls of the lot the test uses (fresh balls at each speed)."""
        return self.balls_per_speed * len(self.speeds_m_s)

    def schedule(self, lot: BallLot) -> list[Slot]:
        """Every slot of the test in firing order: each speed, its fresh balls, each ball's hits."""
        slots: list[Slot] = []
        number = 0
        for speed in self.speeds_m_s:
            for _ in range(self.balls_per_speed):
                number += 1
                for hit in range(1, self.hits_per_ball + 1):
                    slots.append(Slot(len(slots) + 1, speed, number, lot.ball_id(number), hit))
        return slots

    @classmethod
    def load(cls, name_or_path: str | Path) -> BallProcedure:
        """A built-in ball test by name (BALL_BUILTIN) or a TOML file; errors name the field."""
        return load_table(cls, name_or_path, BALL_BUILTIN, "ball test")[0]


@dataclass(frozen=True)
class Slot:
    """One planned hit: its number in the schedule, the speed, the ball and the ball's planned hit."""

    number: int
    speed_m_s: float
    ball_number: int
    ball_id: str
    planned_hit: int
