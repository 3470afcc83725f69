"""Lab temperature and humidity: ENV readings that drift, and their small effect on the ball.

Temperature follows temp_c + temp_swing_c sin(2 pi (start_s + t) / period_s) and humidity moves the opposite
way (a warming room dries), each reading with Gaussian sensor noise. The ball's damping c1 scales
by 1 + damping_per_c (T - 21) + damping_per_pct_rh (RH - 50), using the true (noise-free) values:
a warm, dry ball is livelier (Kagan's humidor studies show the sign, not these sizes). Without this
effect ENV reports a fixed 21 C and 50 % and the ball is unaffected.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import Field

from rig.physics import CollisionParams
from rig.simulators.effects.base import Effect, EffectConfig
from rig.simulators.physics import NOMINAL_RH_PCT, NOMINAL_TEMP_C
from rig.simulators.records import SimBall

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class EnvironmentConfig(EffectConfig):
    """Mean conditions, their slow swing, sensor noise and the ball's sensitivity."""

    kind: Literal["environment"] = "environment"
    slot: ClassVar[str | None] = "environment"
    temp_c: float = Field(21.0, ge=-10.0, le=50.0)
    rh_pct: float = Field(50.0, ge=0.0, le=100.0)
    temp_swing_c: float = Field(1.5, ge=0.0, le=20.0, description="amplitude of the daily-ish swing")
    rh_swing_pct: float = Field(5.0, ge=0.0, le=50.0)
    period_s: float = Field(
        3600.0, ge=1.0, le=1e6, description="period of the swing, virtual s (1 s-12 days)"
    )
    start_s: float = Field(0.0, ge=0.0, le=1e6, description="where in the swing the world starts, virtual s")
    random_start: bool = Field(
        False,
        description="start where the seed and the bat's id put it in the swing (runs start at any hour)",
    )
    noise_c: float = Field(0.05, ge=0.0, le=5.0, description="sensor noise, one sigma")
    noise_pct: float = Field(0.3, ge=0.0, le=10.0)
    damping_per_c: float = Field(-0.005, ge=-0.1, le=0.1, description="relative change of c1 per C")
    damping_per_pct_rh: float = Field(0.002, ge=-0.1, le=0.1, description="relative change of c1 per % RH")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A LabEnvironment."""
        return LabEnvironment(self, scene, rng)


class LabEnvironment(Effect):
    """Fills the `environment` slot and adjusts the ball."""

    config: EnvironmentConfig

    def __init__(self, config: EnvironmentConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        # a lab's runs start at any hour: each bat (and seed) then meets its own point of the swing
        self.start_s = config.start_s
        if config.random_start:
            draw = random.Random(f"{scene.seed}/{scene.bat.id}/environment-start")
            self.start_s = draw.uniform(0.0, config.period_s)

    def true_conditions(self, time_s: float) -> tuple[float, float]:
        """(temperature C, RH %) without sensor noise."""
        c = self.config
        s = math.sin(2.0 * math.pi * (self.start_s + time_s) / c.period_s)
        return c.temp_c + c.temp_swing_c * s, min(100.0, max(0.0, c.rh_pct - c.rh_swing_pct * s))

    def environment(self, time_s: float) -> tuple[float, float]:
        """Sensor readings at virtual time `time_s`."""
        temp, rh = self.true_conditions(time_s)
        temp += self.rng.gauss(0.0, self.config.noise_c)
        rh = min(100.0, max(0.0, rh + self.rng.gauss(0.0, self.config.noise_pct)))
        return temp, rh

    def ball_params(
        self, params: CollisionParams, time_s: float, ball: SimBall | None = None
    ) -> CollisionParams:
        """The ball's damping at the lab's conditions now."""
        temp, rh = self.true_conditions(time_s)
        c = self.config
        scale = 1.0 + c.damping_per_c * (temp - NOMINAL_TEMP_C) + c.damping_per_pct_rh * (rh - NOMINAL_RH_PCT)
        return params.model_copy(update={"c1": params.c1 * scale})
