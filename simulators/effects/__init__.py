"""Optional effects a scene may turn on; each is a small object whose hooks the world calls.

`EffectSpec` is the pydantic discriminated union (on `kind`) a scene file's `[[effects]]` tables
are checked against; `KINDS` maps each kind to its configuration class.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from rig.simulators.effects.base import CHAINED_HOOKS, SLOTS, Effect, EffectConfig, FaultConfig, overrides
from rig.simulators.effects.drag import DragConfig
from rig.simulators.effects.environment import EnvironmentConfig
from rig.simulators.effects.faults_cannon import InterlockConfig, MisfireConfig
from rig.simulators.effects.faults_gates import DoubleTriggerConfig, MissedTriggerConfig
from rig.simulators.effects.faults_link import DroppedReplyConfig, GarbledConfig, UnplugConfig
from rig.simulators.effects.recoil import RecoilConfig
from rig.simulators.effects.scatter import SpeedScatterConfig
from rig.simulators.effects.softening import BarrelSofteningConfig
from rig.simulators.effects.timing import GateTimingConfig
from rig.simulators.effects.trampoline import TrampolineConfig
from rig.simulators.effects.wear import BallWearConfig

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
    | InterlockConfig
    | BarrelSofteningConfig,
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
        BarrelSofteningConfig,
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
