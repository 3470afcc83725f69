"""The NCAA accelerated break-in (ABI) as rules: from what has been recorded, what comes next.

The procedure (NCAA, 30 Sep 2009 [C, lab-practice.md]): barrel compression (BC) at 6 in; BBCOR;
the barrel rolled in about 0.0125 in depth steps until BC has dropped at least 5 % (no rolling if
it has already dropped more than 15 %); BBCOR again; repeated until the bat exceeds the limit or
shows damage. How the 5 % and the 15 % are counted is not in the sources read; this module takes
[inferred]: each stage rolls until BC is 5 % below the stage's own start, and the 15 % counts from
the new bat's BC (a bat that soft is broken in: no more rolling, its BBCOR is retested once and the
ABI ends). Each rolling step goes one step deeper than the last. Pure: `next_step(history)` is
what a plan asks at every point, so a resumed run continues from its record.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class AbiRules(BaseModel):
    """The ABI's numbers ([abi] of protocols/abi.toml)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    procedure: str = Field("bbcor", description="the procedure each stage's BBCOR is measured by [C]")
    location_in: float = Field(6.0, gt=0.0, le=12.0, description="BC location from the barrel end, in [C]")
    stage_drop: float = Field(0.05, gt=0.0, lt=1.0, description="BC drop a stage rolls to [C]")
    broken_in_drop: float = Field(0.15, gt=0.0, lt=1.0, description="BC drop past which no rolling [C]")
    depth_step_in: float = Field(0.0125, gt=0.0, le=0.1, description="rolling depth step, in [C, 'about']")
    passes: int = Field(4, ge=1, le=100, description="passes per rolling step [assumed]")
    max_steps: int = Field(
        12, ge=1, le=100, description="rolling steps in one stage before stopping [assumed]"
    )
    max_stages: int = Field(8, ge=1, le=50, description="stages before the ABI ends [assumed]")

    @classmethod
    def load(cls, path: Path | None = None) -> AbiRules:
        """The rules of an ABI file (default: the built-in protocols/abi.toml)."""
        path = path or Path(__file__).with_name("abi.toml")
        with path.open("rb") as f:
            return cls.model_validate(tomllib.load(f).get("abi", {}))


# -- what the record holds, in order ------------------------------------------------------------
@dataclass(frozen=True)
class Compressed:
    """A BC reading, lbf at the tester's fixed displacement."""

    force_lbf: float


@dataclass(frozen=True)
class Rolled:
    """A rolling step as the operator reported it."""

    depth_in: float
    passes: int
    who: str


@dataclass(frozen=True)
class Measured:
    """A stage's BBCOR with its expanded uncertainty (and the hoop frequency, if measured)."""

    bbcor: float
    expanded_u: float
    hoop_hz: float | None = None


@dataclass(frozen=True)
class Inspected:
    """The operator's answer to "does the barrel show damage?"."""

    damaged: bool


Recorded = Compressed | Rolled | Measured | Inspected


# -- what comes next ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Step:
    """The next thing to do: measure BC, roll (depth, passes), measure BBCOR, inspect, or end."""

    action: Literal["compress", "roll", "bbcor", "inspect", "end"]
    depth_in: float = 0.0
    passes: int = 0
    reason: str = ""


def stages(history: list[Recorded]) -> list[list[Recorded]]:
    """The history cut into stages: each ends with its BBCOR and the inspection after it."""
    out: list[list[Recorded]] = [[]]
    for item in history:
        out[-1].append(item)
        if isinstance(item, Inspected):
            out.append([])
    return out


def next_step(history: list[Recorded], rules: AbiRules, limit: float) -> Step:
    """What the ABI does next after `history` (limit: the BBCOR the bat must not exceed)."""
    cut = stages(history)
    done, stage = cut[:-1], cut[-1]
    if done:
        last = done[-1]
        measured = [x for x in last if isinstance(x, Measured)][-1]
        if measured.bbcor > limit:
            return Step("end", reason=f"BBCOR {measured.bbcor:.4f} exceeds the limit {limit:g}")
        if any(isinstance(x, Inspected) and x.damaged for x in last):
            return Step("end", reason="the barrel shows damage")
        if not any(isinstance(x, Rolled) for x in last) and len(done) > 1:
            return Step("end", reason="broken in: compression had dropped past the no-rolling threshold")
        if len(done) >= rules.max_stages + 1:
            return Step("end", reason=f"{rules.max_stages} rolling stages without exceeding the limit")
    if any(isinstance(x, Measured) for x in stage):
        return Step("inspect")
    readings = [x for x in stage if isinstance(x, Compressed)]
    if not readings or isinstance(stage[-1], Rolled):
        return Step("compress")
    if not done:  # the new bat: its BC, then its BBCOR
        return Step("bbcor")
    new = first_force(history)
    start, now = readings[0].force_lbf, readings[-1].force_lbf
    rolled = [x for x in stage if isinstance(x, Rolled)]
    if not rolled and 1.0 - now / new > rules.broken_in_drop:
        return Step("bbcor", reason=f"compression already {100 * (1 - now / new):.1f} % below the new bat's")
    if 1.0 - now / start >= rules.stage_drop:
        return Step("bbcor")
    if len(rolled) >= rules.max_steps:
        return Step("end", reason=f"{rules.max_steps} rolling steps did not lower the compression enough")
    steps_so_far = sum(isinstance(x, Rolled) for x in history)
    return Step("roll", depth_in=round(rules.depth_step_in * (steps_so_far + 1), 6), passes=rules.passes)


def first_force(history: list[Recorded]) -> float:
    """The new bat's BC (the first reading)."""
    return next(x.force_lbf for x in history if isinstance(x, Compressed))
