"""USA Softball (formerly ASA) batted-ball speed: the versioned table of its test constants.

USA Softball certifies slow-pitch bats by BBS <= 98 mph (since 2004 [C2]), measured on a stationary
bat with the ball fired at the cannon speed: 110 mph until 30 Sep 2012, 105 mph from 1 Oct 2012, the
limit kept [C2]; the swing-speed constants changed with the cannon speed [C2] but their values were
not found [U]. Each edition below therefore states its constants with their status:

- the cannon speed and the dates: [C2] (lab-practice notes, "Other standards");
- the pitch speed and the bat speed at the reference point: [U], assumed so that pitch + bat equals
  the cannon speed (the relative speed the cannon reproduces, as BESR's 70 + 66 = 136 mph [I]);
- the swing's geometry (bat turning about a point 6 in from the knob, the reference point 6 in from
  the barrel end, speed proportional to radius): [U], the BESR kinematics the BBS procedure uses.

Because the geometry is the BESR kinematics', an edition's bat speed at any impact point is the
BESR swing's (SwingModel, 66 mph at the reference point) scaled by bat_speed / 66 mph.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date

from rig.core.errors import ConfigError
from rig.core.units import INCH, MPH

LIMIT_M_S = 98.0 * MPH  # [C2] BBS <= 98 mph, adopted 2004
BESR_REFERENCE_BAT_SPEED_M_S = 66.0 * MPH  # SwingModel's default: the speed the editions' scale from
SWING_PIVOT_FROM_KNOB_M = 6.0 * INCH  # [U] the BESR kinematics' swing centre
REFERENCE_FROM_TIP_M = 6.0 * INCH  # [U] the BESR kinematics' reference point


@dataclass(frozen=True)
class SoftballEdition:
    """One edition of the USA Softball BBS test: in force from `effective`, its speeds (m/s)."""

    key: str  # the edition's year, which names its metric (usas_bbs_<key>)
    effective: date  # [C2]
    cannon_speed_m_s: float  # [C2] the ball's speed at the stationary bat
    pitch_speed_m_s: float  # [U]
    bat_speed_m_s: float  # [U] at the reference point, REFERENCE_FROM_TIP_M from the barrel end
    note: str

    @property
    def metric_name(self) -> str:
        """The registry's name of this edition's BBS metric."""
        return f"usas_bbs_{self.key}"

    def bat_speed(self, besr_bat_speed_m_s: float) -> float:
        """The bat's speed at an impact point from the BESR swing's speed there (same geometry)."""
        return besr_bat_speed_m_s * self.bat_speed_m_s / BESR_REFERENCE_BAT_SPEED_M_S

    def bbs(self, e_a: float, besr_bat_speed_m_s: float) -> float:
        """BBS = V_pitch e_A + V_bat (1 + e_A) with this edition's constants (m/s)."""
        return self.pitch_speed_m_s * e_a + self.bat_speed(besr_bat_speed_m_s) * (1.0 + e_a)


EDITIONS: tuple[SoftballEdition, ...] = (
    SoftballEdition(
        "2004",
        date(2004, 1, 1),  # [C2] the year only; the 1st of January assumed [U]
        110.0 * MPH,  # [C2]
        25.0 * MPH,  # [U]
        85.0 * MPH,  # [U] 110 - 25 mph
        "cannon 110 mph [C2]; pitch 25 mph, bat 85 mph at 6 in from the barrel end [U]",
    ),
    SoftballEdition(
        "2012",
        date(2012, 10, 1),  # [C2]
        105.0 * MPH,  # [C2]
        25.0 * MPH,  # [U]
        80.0 * MPH,  # [U] 105 - 25 mph
        "cannon 105 mph [C2]; pitch 25 mph, bat 80 mph at 6 in from the barrel end [U]",
    ),
)
FAMILY = "usas_bbs"  # a procedure's `standard` that the edition date resolves to one edition's metric


def edition_on(day: date) -> SoftballEdition:
    """The edition in force on `day`; ConfigError before the first one."""
    in_force = [e for e in EDITIONS if e.effective <= day]
    if not in_force:
        raise ConfigError(
            f"no USA Softball BBS edition in force on {day.isoformat()}; the first is "
            f"{EDITIONS[0].effective.isoformat()}"
        )
    return max(in_force, key=lambda e: e.effective)
