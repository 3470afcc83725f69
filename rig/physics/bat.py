"""The pivoted bat: the barrel's hoop mode on a rigid bat body free to turn about the pivot.

Assumptions (each a modelling choice, stated so a bat engineer can judge it):
1. During the ~1 ms contact the bat turns through a small angle, so the body's rotation about
   the pivot acts at the impact point as a translating mass M = I/Q^2 (I: MOI about the pivot,
   Q: pivot-to-impact distance). The pivot's reaction is implicit in that reduction.
2. The hoop-mode mass m2 is part of the bat, so the rigid body carrying it has M - m2; with a
   rigid barrel the ball meets the whole effective mass I/Q^2. This needs I/Q^2 > m2.
3. The barrel spring k2 = m2 (2 pi f_hoop)^2 and damper c2 act between the hoop mass and the body;
   bending modes, the ball's spin and gravity are left out.
4. The apparent COR is e_A = rebound speed / inbound speed of the ball (stationary bat), and
   BBCOR = e_A (1 + k) + k with k = m_ball Q^2 / I (founding paper, Eq. 5); BESR = e_A + 1/2.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.core.errors import ParameterError
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams


class PivotedBat(BaseModel):
    """A bat on the pivot: MOI about the pivot and where the ball strikes."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    moi_kgm2: float = Field(gt=0.0, description="moment of inertia about the pivot, kg m^2")
    impact_from_pivot_m: float = Field(gt=0.0, description="pivot-to-impact distance Q, m")

    @classmethod
    def build(cls, **values: float) -> PivotedBat:
        """Validate and build; a refused value raises ParameterError naming the parameter."""
        try:
            return cls(**values)
        except ValidationError as exc:
            raise ParameterError.from_validation(exc) from None

    @property
    def effective_mass(self) -> float:
        """The bat's mass as the ball sees it at the impact point, I/Q^2, kg."""
        return self.moi_kgm2 / self.impact_from_pivot_m**2

    def recoil_factor(self, ball_mass: float) -> float:
        """k = m_ball Q^2 / I of Eq. 5."""
        return ball_mass / self.effective_mass


def bbcor_from_ea(e_a: float, k: float) -> float:
    """BBCOR = e_A (1 + k) + k (founding paper, Eq. 5)."""
    return e_a * (1.0 + k) + k


def ea_from_bbcor(bbcor: float, k: float) -> float:
    """Inverse of Eq. 5: e_A = (BBCOR - k) / (1 + k)."""
    return (bbcor - k) / (1.0 + k)


@dataclass(frozen=True)
class BatPrediction:
    """What the model predicts the rig will measure for this bat at this speed."""

    speed: float
    hoop_hz: float | None
    e_a: float
    bbcor: float
    besr: float
    k: float
    effective_mass_kg: float
    contact_time_s: float


def impact_for(params: CollisionParams, speed: float, hoop_hz: float | None, bat: PivotedBat) -> Impact:
    """The collision of the ball with this bat's barrel on its free body."""
    body = bat.effective_mass - params.m2
    if body <= 0.0:
        raise ParameterError(
            "moi_kgm2",
            bat.moi_kgm2,
            f"I/Q^2 = {bat.effective_mass:.4g} kg must exceed the barrel mass m2 = {params.m2:g} kg",
        )
    return Impact(params, speed, hoop_hz, body_mass=body)


def predict_bat(
    params: CollisionParams,
    speed: float,
    hoop_hz: float | None,
    bat: PivotedBat,
    rtol: float = fast.DEFAULT_RTOL,
) -> BatPrediction:
    """e_A, BBCOR and BESR the model predicts for a stationary bat hit at `speed`."""
    res = fast.solve(impact_for(params, speed, hoop_hz, bat), rtol=rtol)
    k = bat.recoil_factor(params.m1)
    e_a = res.cor
    return BatPrediction(
        speed=speed,
        hoop_hz=hoop_hz,
        e_a=e_a,
        bbcor=bbcor_from_ea(e_a, k),
        besr=e_a + 0.5,
        k=k,
        effective_mass_kg=bat.effective_mass,
        contact_time_s=res.contact_time_s,
    )
