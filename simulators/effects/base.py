"""The effect protocol: an effect overrides some hooks, and the world calls only those.

Two kinds of hook:
- chained hooks (methods of `Effect` below): every effect of the scene that overrides one is
  called in scene order, each transforming the value the previous one returned;
- slots: a component the world otherwise takes from `rig.simulators.physics` (flight, collision,
  tick latching, recoil, lab environment). An effect whose configuration names a `slot` is that
  component; a scene may fill each slot once.

The world inspects the effects once, when it is built, so an effect a scene leaves out costs
nothing per shot: no call, no branch on a flag.
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, Annotated, ClassVar

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from rig.physics import CollisionParams
from rig.simulators.records import Crossing, Outgoing, SimBall

if TYPE_CHECKING:
    from rig.simulators.scene import Scene
    from rig.simulators.world import SimWorld

CHAINED_HOOKS = (
    "launch_speed",
    "ball_params",
    "crossings",
    "misfire",
    "after_arm",
    "outgoing",
    "unplug_after",
)
SLOTS = ("flight", "collision", "ticks", "recoil", "environment")

Probability = Annotated[float, Field(ge=0.0, le=1.0)]
ShotNumber = Annotated[int, Field(ge=1, le=10_000)]  # a run fires tens of shots; a ball lasts ~1000


class EffectConfig(BaseModel):
    """Common fields of every effect's configuration (each subclass adds `kind` and its own)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    slot: ClassVar[str | None] = None  # the default component this effect replaces, if any
    enabled: StrictBool = Field(True, description="false: listed but left out (costs nothing)")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """The effect object this configuration describes."""
        raise NotImplementedError


class FaultConfig(EffectConfig):
    """A fault strikes on the listed shots, and/or at random with the scene's seed."""

    shots: tuple[ShotNumber, ...] = Field(
        (), max_length=1000, description="shot numbers (1-based FIRE count) it strikes"
    )
    probability: Probability = Field(0.0, description="chance per opportunity, drawn with the scene seed")


class Effect:
    """Base of every effect; the default hooks do nothing and are never called."""

    def __init__(self, config: EffectConfig, scene: Scene, rng: random.Random) -> None:
        self.config = config
        self.scene = scene
        self.rng = rng
        self.slot = config.slot

    def launch_speed(self, speed: float) -> float:
        """The muzzle speed of this shot, m/s."""
        return speed

    def ball_params(
        self, params: CollisionParams, time_s: float, ball: SimBall | None = None
    ) -> CollisionParams:
        """The ball's model constants for this shot (`ball`: the ball fired, with its hits so far)."""
        return params

    def crossings(self, crossings: list[Crossing], shot: int) -> list[Crossing]:
        """The beam breaks the gates see, before the counter latches them."""
        return crossings

    def misfire(self, shot: int) -> bool:
        """True if FIRE of this shot fails to launch a ball."""
        return False

    def after_arm(self, world: SimWorld, shot: int) -> None:
        """Called just after ARM is accepted for this shot."""

    def outgoing(self, message: Outgoing) -> bytes | None:
        """The bytes actually sent for `message` (None: nothing is sent)."""
        return message.data

    def unplug_after(self, device: str, shot: int) -> int | None:
        """Unplug `device` after this many of its messages caused by the shot (None: stay)."""
        return None


def overrides(effect: Effect, hook: str) -> bool:
    """True if the effect's class overrides chained hook `hook`."""
    return getattr(type(effect), hook) is not getattr(Effect, hook)


class Strikes:
    """When a fault strikes: on listed shots (once each) or with its probability per chance."""

    def __init__(self, config: FaultConfig, rng: random.Random) -> None:
        self.shots = frozenset(config.shots)
        self.probability = config.probability
        self.rng = rng
        self._spent: set[int] = set()

    def now(self, shot: int) -> bool:
        """Decide for one opportunity in `shot`; a listed shot strikes only its first opportunity."""
        if shot in self.shots and shot not in self._spent:
            self._spent.add(shot)
            return True
        # Only draw when a probability is set, so a purely scheduled fault uses no random numbers.
        return self.probability > 0.0 and self.rng.random() < self.probability
