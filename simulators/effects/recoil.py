"""Bat recoil: the pivot encoder reports the bat's angular speed after each impact.

Angular momentum about the pivot is conserved through the ~1 ms contact, so the bat leaves with
omega = m_ball Q (v_in + v_out) / I (I about the pivot, Q pivot to impact). Without this effect the
clamp sends no `! RECOIL` events.
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import Field

from rig.simulators.effects.base import Effect, EffectConfig

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


class RecoilConfig(EffectConfig):
    """Encoder noise, relative (0: exact)."""

    kind: Literal["recoil"] = "recoil"
    slot: ClassVar[str | None] = "recoil"
    noise_rel: float = Field(0.0, ge=0.0, le=0.2, description="relative one-sigma encoder noise")

    def build(self, scene: Scene, rng: random.Random) -> Effect:
        """A Recoil."""
        return Recoil(self, scene, rng)


class Recoil(Effect):
    """Fills the `recoil` slot."""

    config: RecoilConfig

    def recoil(self, m_ball: float, q: float, v_in: float, v_out: float) -> float:
        """omega = m Q (v_in + v_out) / I, rad/s, with the encoder's noise."""
        omega = m_ball * q * (v_in + v_out) / self.scene.bat.moi_kgm2
        if self.config.noise_rel:
            omega *= 1.0 + self.rng.gauss(0.0, self.config.noise_rel)
        return omega
