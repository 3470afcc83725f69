"""Optional effects a scene may turn on; each is a small object whose hooks the world calls.

`EffectSpec` is the pydantic discriminated union (on `kind`) a scene file's `[[effects]]` tables
are checked against; `KINDS` maps each kind to its configuration class.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from simulators.effects.base import CHAINED_HOOKS, SLOTS, Effect, EffectConfig, FaultConfig, overrides
from simulators.effects.drag import DragConfig
from simulators.effects.environment import EnvironmentConfig
from simulators.effects.faults_cannon import InterlockConfig, MisfireConfig
from simulators.effects.faults_gates import DoubleTriggerConfig, MissedTriggerConfig
from simulators.effects.faults_link import DroppedReplyConfig, GarbledConfig, UnplugConfig
from simulators.effects.recoil import RecoilConfig
from simulators.effects.scatter import SpeedScatterConfig
from simulators.effects.timing import GateTimingConfig
from simulators.effects.trampoline import TrampolineConfig
from simulators.effects.wear import BallWearConfig

EffectSpec = Annotated[
    SpeedScatterConfig
    | GateTimingConfig
    | DragConfig
    | TrampolineConfig
    | RecoilConfig
    | BallWearConfig
    | EnvironmentConfig
    | MissedTriggerConfig
    | DoubleTriggerConfig
    | GarbledConfig
    | DroppedReplyConfig
    | UnplugConfig
    | MisfireConfig
    | InterlockConfig,
    Field(discriminator="kind"),
]

KINDS: dict[str, type[EffectConfig]] = {
    cls.model_fields["kind"].default: cls
    for cls in (
        SpeedScatterConfig,
        GateTimingConfig,
        DragConfig,
        TrampolineConfig,
        RecoilConfig,
        BallWearConfig,
        EnvironmentConfig,
        MissedTriggerConfig,
        DoubleTriggerConfig,
        GarbledConfig,
        DroppedReplyConfig,
        UnplugConfig,
        MisfireConfig,
        InterlockConfig,
    )
}

__all__ = [
    "CHAINED_HOOKS",
    "KINDS",
    "SLOTS",
    "Effect",
    "EffectConfig",
    "EffectSpec",
    "FaultConfig",
    "overrides",
]
