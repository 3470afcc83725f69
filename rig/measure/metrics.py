"""The founding paper's performance metrics from one stationary-bat shot.

Sources: the founding paper (hoop-frequency paper, section 4.2, Eqs. 3-5), the WSU SSL glossary
(e_A, BESR = e_A + 1/2, BBCOR), Nathan BRJ 2003 (original BESR kinematics) and Nathan AJP 2003
(BBS). Every metric's formula and source is declared once in rig.measure.registry (DEFINITIONS,
which each MetricSet carries); a registered metric is computed with the built-in ones.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.errors import ParameterError
from rig.core.units import INCH, MPH
from rig.measure.registry import DEFINITIONS, MetricTerms, bbcor, bbs, besr, ea_from_bbcor, metric, metrics

BESR_REFERENCE_SPEED_M_S = 136.0 * MPH  # 70 mph pitch + 66 mph bat = 60.8 m/s (docs/standards.md, section 1)


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
    terms: MetricTerms = field(repr=False, compare=False)  # what the metrics were computed from
    added: MappingProxyType[str, float] = field(default_factory=lambda: MappingProxyType({}))  # registered
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
            **({} if self.terms.ball_cor is None else {"ball_cor": self.terms.ball_cor}),
            **self.added,
        }

    def value(self, name: str) -> float:
        """A metric's value by its registry name (ConfigError for a name the registry lacks)."""
        values = {"bbcor": self.bbcor, "besr": self.besr, "bbs": self.bbs, **self.added}
        return values[metric(name).name]


def recorded_terms(metrics: Mapping[str, Any]) -> MetricTerms:
    """A shot's MetricTerms from its recorded metrics: k, V_bat, the default swing's pitch speed
    (the one every shot's metrics are computed with) and the run's ball COR where it had one."""
    return MetricTerms(
        k=metrics["k"],
        v_bat=metrics["v_bat"],
        v_pitch=DEFAULT_SWING.pitch_speed_m_s,
        ball_cor=metrics.get("ball_cor"),
    )


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
    ball_cor: float | None = None,
) -> MetricSet:
    """All metrics of a stationary-bat shot (speeds m/s, Q m, I kg m^2, mass kg, length m), each
    registered metric by its registry formula; those divided by the ball's COR (BPF) only with
    `ball_cor`, the run's ball COR on the rigid wall."""
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
    if ball_cor is not None and not 0.0 < ball_cor <= 1.0:
        raise ParameterError("ball_cor", ball_cor, "must lie in (0, 1]")
    terms = MetricTerms(k=k, v_bat=v_bat, v_pitch=swing.pitch_speed_m_s, ball_cor=ball_cor)
    values = {m.name: m.value(e_a, terms) for m in metrics() if ball_cor is not None or not m.needs_ball_cor}
    return MetricSet(
        e_a=e_a,
        bbcor=values.pop("bbcor"),
        besr=values.pop("besr"),
        bbs=values.pop("bbs"),
        k=k,
        v_bat=v_bat,
        besr_eq3=eq3,
        terms=terms,
        added=MappingProxyType(values),
    )


__all__ = [
    "BESR_REFERENCE_SPEED_M_S",
    "DEFAULT_SWING",
    "DEFINITIONS",
    "MetricSet",
    "SwingModel",
    "bbcor",
    "bbs",
    "besr",
    "besr_eq3",
    "collision_efficiency",
    "compute_metrics",
    "ea_from_bbcor",
    "recoil_factor",
    "recorded_terms",
]
