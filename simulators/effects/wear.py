"""Ball wear: the ball softens with every hit, so its COR drifts down over a run.

Modelled as the ball's damping coefficient c1 rising by `damping_per_hit` (relative) per previous
hit of that ball: c1_n = c1 (1 + damping_per_hit n) for its (n+1)-th hit. With the paper's
constants a 1 % rise of c1 lowers e_A by about 1 %. Each ball counts its own hits: a ball the host
LOADs for the first time starts fresh (the world keeps the count). A host that never names its
balls fires one ball all along, whose count never resets.
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Literal

from pydantic import Field

from rig.physics import CollisionParams
from rig.simulators.effects.base import Effect, EffectConfig
from rig.simulators.records import SimBall

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class BallWearConfig(EffectConfig):
    """Relative rise of the ball's damping per hit."""

    kind: Literal["ball_wear"] = "ball_wear"
    damping_per_hit: float = Field(0.001, ge=0.0, le=0.1, description="relative rise of c1 per hit")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A BallWear."""
        return BallWear(self, scene, rng)


class BallWear(Effect):
    """Raises c1 with the fired ball's hit count."""

    config: BallWearConfig

    def __init__(self, config: BallWearConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.hits = 0  # for a call without a ball: one ball all along

    def ball_params(
        self, params: CollisionParams, time_s: float, ball: SimBall | None = None
    ) -> CollisionParams:
        """The worn ball's constants for this hit (called once per impact)."""
        hits = ball.hits if ball is not None else self.hits
        self.hits += 1
        return params.model_copy(update={"c1": params.c1 * (1.0 + self.config.damping_per_hit * hits)})
