"""Cannon speed scatter: shot-to-shot spread of the muzzle speed at a given pressure."""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Literal

from pydantic import Field

from rig.simulators.effects.base import Effect, EffectConfig

if TYPE_CHECKING:
    from rig.simulators.scene import Scene

# A draw this many sigmas out is clipped, so a wild draw can never reverse the ball.
_CLIP_SIGMAS = 5.0


class SpeedScatterConfig(EffectConfig):
    """Gaussian relative scatter of the muzzle speed."""

    kind: Literal["speed_scatter"] = "speed_scatter"
    sigma_rel: float = Field(0.005, ge=0.0, le=0.1, description="relative standard deviation")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A SpeedScatter."""
        return SpeedScatter(self, scene, rng)


class SpeedScatter(Effect):
    """Multiplies the curve's muzzle speed by 1 + N(0, sigma_rel)."""

    config: SpeedScatterConfig

    def launch_speed(self, speed: float) -> float:
        """Scattered muzzle speed, m/s."""
        z = max(-_CLIP_SIGMAS, min(_CLIP_SIGMAS, self.rng.gauss(0.0, 1.0)))
        return speed * (1.0 + self.config.sigma_rel * z)
