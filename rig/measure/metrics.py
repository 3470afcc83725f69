"""The founding paper's performance metrics from one stationary-bat shot.

Sources: the founding paper (hoop-frequency paper, section 4.2, Eqs. 3-5), the WSU SSL glossary
(e_A, BESR = e_A + 1/2, BBCOR), Nathan BRJ 2003 (original BESR kinematics) and Nathan AJP 2003
(BBS). Every metric's formula and source is in DEFINITIONS, which each MetricSet carries.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.errors import ParameterError
from rig.core.units import INCH, MPH

BESR_REFERENCE_SPEED_M_S = 136.0 * MPH  # 70 mph pitch + 66 mph bat = 60.8 m/s (docs/standards.md, section 1)

DEFINITIONS: MappingProxyType[str, str] = MappingProxyType(
    {
        "e_a": "e_A = v_out / v_in, stationary bat (collision efficiency; WSU SSL glossary)",
        "k": "k = m_ball Q^2 / I, Q pivot-to-impact, I MOI about the pivot (founding paper, Eq. 5)",
        "bbcor": "BBCOR = e_A (1 + k) + k (founding paper, Eq. 5; WSU SSL glossary, stationary bat)",
        "besr": "BESR = e_A + 1/2 (WSU SSL glossary; ASTM F2219; Falcon BESR sheet, rearranged)",
        "besr_eq3": (
            "BESR_Eq3 = (v_out - dv)/(v_in - dv) + 1/2, dv = 60.8 m/s - V_contact (founding paper, "
            "Eq. 3, as printed); equals e_A + 1/2 only when dv = 0, i.e. V_contact = 60.8 m/s"
        ),
        "bbs": (
            "BBS = V_pitch e_A + V_bat (e_A + 1) (founding paper, Eq. 4; Nathan AJP 2003), "
            "V_bat from the SwingModel (original BESR kinematics, Nathan BRJ 2003)"
        ),
        "v_bat": "V_bat(Q) = V_ref r(Q) / r_ref: rigid rotation about the swing pivot (SwingModel)",
    }
)


class SwingModel(BaseModel):
    """Bat speed at the impact point for BBS: rigid rotation about a fixed swing pivot.

    Default: the original BESR kinematics (Nathan, BRJ 2003) - pitch 70 mph, bat turning about a
    point 6 in from the knob with 66 mph at a point 6 in from the barrel end, so for a bat of
    length L hit at Q from the rig's pivot, V_bat = 66 mph * r / (L - 12 in), r the impact's
    radius about the swing pivot (r = Q when both pivots are 6 in from the knob).
    Unknown: the NCAA never published bat speed as a function of MOI (docs/standards.md, [U]); Nathan
    et al. 2011 fit angular speed ~ 1/I_knob but the coefficients are unreadable, so the fixed-speed
    BESR kinematics is the default. Falcon's BESR sheet implies a swing pivot 5.375 in from the
    knob; set `swing_pivot_from_knob_m` to use it.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    pitch_speed_m_s: float = Field(70.0 * MPH, gt=0.0, description="pitched ball speed")
    reference_speed_m_s: float = Field(66.0 * MPH, gt=0.0, description="bat speed at the reference point")
    reference_from_tip_m: float = Field(6.0 * INCH, ge=0.0, description="reference point from barrel end")
    swing_pivot_from_knob_m: float = Field(6.0 * INCH, ge=0.0, description="swing rotation centre")
    rig_pivot_from_knob_m: float = Field(PIVOT_FROM_KNOB_M, ge=0.0, description="the clamp pivot (F2398)")

    def bat_speed(self, q_m: float, bat_length_m: float) -> float:
        """Speed of the bat at the impact point, m/s (rigid rotation: proportional to radius)."""
        r_ref = bat_length_m - self.swing_pivot_from_knob_m - self.reference_from_tip_m
        if r_ref <= 0.0:
            raise ParameterError("bat_length_m", bat_length_m, "shorter than the swing model's radii")
        r = q_m + self.rig_pivot_from_knob_m - self.swing_pivot_from_knob_m
        return self.reference_speed_m_s * r / r_ref


DEFAULT_SWING = SwingModel()


def collision_efficiency(v_in: float, v_out: float) -> float:
    """e_A = v_out / v_in for a stationary bat."""
    return v_out / v_in


def recoil_factor(q_m: float, moi_kgm2: float, ball_mass_kg: float) -> float:
    """k = m_ball Q^2 / I (founding paper, Eq. 5)."""
    return ball_mass_kg * q_m**2 / moi_kgm2


def bbcor(e_a: float, k: float) -> float:
    """BBCOR = e_A (1 + k) + k (founding paper, Eq. 5)."""
    return e_a * (1.0 + k) + k


def ea_from_bbcor(bbcor_value: float, k: float) -> float:
    """Inverse of Eq. 5: e_A = (BBCOR - k) / (1 + k)."""
    return (bbcor_value - k) / (1.0 + k)


def besr(e_a: float) -> float:
    """BESR = e_A + 1/2 (WSU SSL glossary; ASTM F2219)."""
    return e_a + 0.5


def besr_eq3(
    v_in: float, v_out: float, v_contact: float, reference_m_s: float = BESR_REFERENCE_SPEED_M_S
) -> float:
    """The paper's Eq. 3 as printed: (v_out - dv)/(v_in - dv) + 1/2 with dv = 60.8 m/s - V_contact.

    It equals e_A + 1/2 only if dv (1 - e_A) = 0, i.e. V_contact = 60.8 m/s (or e_A = 1); it is
    singular at v_in = dv (e.g. V_contact = 0 with a 60.8 m/s shot). See docs/measurement.md.
    """
    dv = reference_m_s - v_contact
    den = v_in - dv
    if abs(den) <= 1e-9 * max(abs(v_in), 1.0):
        raise ParameterError("v_contact", v_contact, f"Eq. 3 is singular: v_in = dv = {dv:.6g} m/s")
    return (v_out - dv) / den + 0.5


def bbs(e_a: float, v_pitch: float, v_bat: float) -> float:
    """BBS = V_pitch e_A + V_bat (e_A + 1) (founding paper, Eq. 4)."""
    return v_pitch * e_a + v_bat * (e_a + 1.0)


@dataclass(frozen=True)
class MetricSet:
    """One shot's metrics; `definitions` names each formula and its source."""

    e_a: float
    bbcor: float
    besr: float
    bbs: float
    k: float
    v_bat: float  # the SwingModel's bat speed at the impact point, m/s
    besr_eq3: float | None  # None where Eq. 3 is singular
    definitions: MappingProxyType[str, str] = field(
        default_factory=lambda: DEFINITIONS, repr=False, compare=False
    )

    def as_dict(self) -> dict[str, float | None]:
        """The values, keyed like DEFINITIONS (for the store and reports)."""
        return {
            "e_a": self.e_a,
            "bbcor": self.bbcor,
            "besr": self.besr,
            "besr_eq3": self.besr_eq3,
            "bbs": self.bbs,
            "k": self.k,
            "v_bat": self.v_bat,
        }


class _ShotValues(BaseModel):
    model_config = ConfigDict(frozen=True, allow_inf_nan=False)

    v_in: float = Field(gt=0.0)
    v_out: float = Field(ge=0.0)
    q_m: float = Field(gt=0.0)
    moi_kgm2: float = Field(gt=0.0)
    ball_mass_kg: float = Field(gt=0.0)
    bat_length_m: float = Field(gt=0.0)


def compute_metrics(
    v_in: float,
    v_out: float,
    q_m: float,
    moi_kgm2: float,
    ball_mass_kg: float,
    bat_length_m: float,
    swing: SwingModel = DEFAULT_SWING,
) -> MetricSet:
    """All metrics of a stationary-bat shot (speeds m/s, Q m, I kg m^2, mass kg, length m)."""
    try:
        _ShotValues(
            v_in=v_in,
            v_out=v_out,
            q_m=q_m,
            moi_kgm2=moi_kgm2,
            ball_mass_kg=ball_mass_kg,
            bat_length_m=bat_length_m,
        )
    except ValidationError as exc:
        raise ParameterError.from_validation(exc) from None
    e_a = collision_efficiency(v_in, v_out)
    k = recoil_factor(q_m, moi_kgm2, ball_mass_kg)
    v_bat = swing.bat_speed(q_m, bat_length_m)
    try:
        eq3: float | None = besr_eq3(v_in, v_out, v_bat)
    except ParameterError:
        eq3 = None
    return MetricSet(
        e_a=e_a,
        bbcor=bbcor(e_a, k),
        besr=besr(e_a),
        bbs=bbs(e_a, swing.pitch_speed_m_s, v_bat),
        k=k,
        v_bat=v_bat,
        besr_eq3=eq3,
    )
