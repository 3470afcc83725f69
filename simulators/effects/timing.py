"""Gate timing: trigger jitter, per-gate latency and a counter that truncates, not rounds.

Without this effect a beam break is latched at the nearest tick of its exact time. With it, each
break is delayed by the gate's fixed latency plus Gaussian jitter, and the counter - whose clock
runs independently of the ball - latches floor(t / tick + phase) with one random phase per world.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING, Annotated, ClassVar, Literal

from pydantic import Field

from rig.simulators.effects.base import Effect, EffectConfig

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class GateTimingConfig(EffectConfig):
    """Jitter (ns, one sigma) and fixed latency per gate (ns; missing gates get 0)."""

    kind: Literal["gate_timing"] = "gate_timing"
    slot: ClassVar[str | None] = "ticks"
    jitter_ns: float = Field(20.0, ge=0.0, le=1e5, description="trigger jitter, one sigma, ns")
    latency_ns: tuple[Annotated[float, Field(ge=-1e6, le=1e6)], ...] = Field(
        (), max_length=16, description="fixed trigger delay of gate 1, 2, ... in ns (within +-1 ms)"
    )

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A GateTiming."""
        return GateTiming(self, scene, rng)


class GateTiming(Effect):
    """Fills the `ticks` slot."""

    config: GateTimingConfig

    def __init__(self, config: GateTimingConfig, scene: Scene, rng: random.Random) -> None:
        super().__init__(config, scene, rng)
        self.tick_s = scene.rig.tick_ns * 1e-9
        self.phase = rng.random()

    def latch(self, gate: int, time_s: float) -> int:
        """floor((t + latency + jitter) / tick + phase)."""
        lat = self.config.latency_ns
        delay_ns = (lat[gate - 1] if gate <= len(lat) else 0.0) + self.rng.gauss(0.0, self.config.jitter_ns)
        return math.floor((time_s + delay_ns * 1e-9) / self.tick_s + self.phase)
