"""Physics checks on one shot: reasons to re-shoot (the shot is INVALID), never a verdict on the bat.

Each reason has a stable code (for the store and for statistics) and a sentence for the operator.
Notes (`invalidates=False`) are recorded but do not by themselves void the shot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from pydantic import BaseModel, ConfigDict, Field

from rig.core.devices import Recoil
from rig.core.units import MPH
from rig.measure.speeds import GatePasses, ShotSpeeds


class Code(StrEnum):
    """Stable reason codes; never rename one (stored records use them)."""

    PAIRS_DISAGREE = "PAIRS_DISAGREE"
    REBOUND_FAST = "REBOUND_FAST"
    SPEED_OUT_OF_TOLERANCE = "SPEED_OUT_OF_TOLERANCE"
    NO_INBOUND = "NO_INBOUND"
    NO_REBOUND = "NO_REBOUND"
    RECOIL_MISMATCH = "RECOIL_MISMATCH"
    DOUBLE_TRIGGER = "DOUBLE_TRIGGER"
    MISSED_GATE = "MISSED_GATE"


@dataclass(frozen=True)
class Invalidity:
    """One reason: code, a sentence, whether it voids the shot, and the numbers behind it."""

    code: Code
    message: str
    invalidates: bool = True
    measured: float | None = None
    limit: float | None = None


class ValidityLimits(BaseModel):
    """Tolerances of the validity checks. None of them is published (docs/standards.md [U])."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    pair_tolerance_rel: float = Field(0.01, gt=0.0, description="inbound 1-2 vs 2-3, after drag")
    drag_per_m: float = Field(0.003, ge=0.0, description="relative speed loss per metre of flight")
    speed_tolerance_m_s: float = Field(1.0 * MPH, gt=0.0, description="|v_in - target| allowed")
    recoil_tolerance_rel: float = Field(0.10, gt=0.0, description="measured vs expected recoil omega")
    double_trigger_invalidates: bool = Field(False, description="extra crossings void the shot")
    require_inbound_cross_check: bool = Field(True, description="a missing inbound gate voids the shot")


DEFAULT_LIMITS = ValidityLimits()


def expected_pair_ratio(positions_m: tuple[float, float, float], drag_per_m: float) -> float:
    """Expected inbound (2-3 speed)/(1-2 speed): drag slows the ball between the pairs' midpoints."""
    x1, x2, x3 = positions_m
    return math.exp(-drag_per_m * ((x1 + x2) / 2.0 - (x2 + x3) / 2.0))


def expected_recoil(v_in: float, v_out: float, q_m: float, moi_kgm2: float, ball_mass_kg: float) -> float:
    """Bat angular speed from angular momentum about the pivot: m Q (v_in + v_out) / I, rad/s."""
    return ball_mass_kg * q_m * (v_in + v_out) / moi_kgm2


def check_shot(
    speeds: ShotSpeeds,
    passes: GatePasses,
    target_speed_m_s: float | None,
    recoil: Recoil | None,
    q_m: float,
    moi_kgm2: float,
    ball_mass_kg: float,
    limits: ValidityLimits = DEFAULT_LIMITS,
    *,
    positions_m: tuple[float, float, float] = (0.75, 0.50, 0.25),
    inbound_at_impact_m_s: float | None = None,
) -> list[Invalidity]:
    """Every reason this shot should be re-shot (or noted); an empty list means valid.

    `target_speed_m_s` None skips the speed check, `recoil` None the recoil check; `positions_m`
    (gate distances from the impact, gate 1 first) sets the drag allowance between the pairs.
    The target is a speed at the bat: `inbound_at_impact_m_s` (the gate speed corrected for drag)
    is held to it where given, else the gate speed itself.
    """
    out: list[Invalidity] = []
    out += _pass_notes(passes, limits)
    v_in, v_out = speeds.inbound, speeds.rebound
    if v_in is None:
        out.append(
            Invalidity(Code.NO_INBOUND, "No inbound speed: the ball did not cross two gates on the way in.")
        )
    if v_out is None:
        out.append(
            Invalidity(Code.NO_REBOUND, "No rebound speed: the ball did not come back through two gates.")
        )
    if speeds.inbound_far is not None and speeds.inbound_near is not None:
        ratio = speeds.inbound_near / speeds.inbound_far
        expected = expected_pair_ratio(positions_m, limits.drag_per_m)
        dev = ratio / expected - 1.0
        if abs(dev) > limits.pair_tolerance_rel:
            out.append(
                Invalidity(
                    Code.PAIRS_DISAGREE,
                    f"Inbound speeds disagree: gates 1-2 {speeds.inbound_far:.3f} m/s, "
                    f"gates 2-3 {speeds.inbound_near:.3f} m/s ({dev:+.2%} after drag; "
                    f"limit +-{limits.pair_tolerance_rel:.2%}).",
                    measured=dev,
                    limit=limits.pair_tolerance_rel,
                )
            )
    if v_in is not None and v_out is not None and v_out >= v_in:
        out.append(
            Invalidity(
                Code.REBOUND_FAST,
                f"Rebound {v_out:.3f} m/s is not slower than inbound {v_in:.3f} m/s: energy cannot rise.",
                measured=v_out / v_in,
                limit=1.0,
            )
        )
    if v_in is not None and target_speed_m_s is not None:
        at_bat = v_in if inbound_at_impact_m_s is None else inbound_at_impact_m_s
        where = "" if inbound_at_impact_m_s is None else " at the impact point"
        miss = at_bat - target_speed_m_s
        if abs(miss) > limits.speed_tolerance_m_s:
            out.append(
                Invalidity(
                    Code.SPEED_OUT_OF_TOLERANCE,
                    f"Inbound {at_bat:.3f} m/s{where} is {miss:+.3f} m/s from the target "
                    f"{target_speed_m_s:.3f} m/s "
                    f"(limit +-{limits.speed_tolerance_m_s:.3f} m/s).",
                    measured=miss,
                    limit=limits.speed_tolerance_m_s,
                )
            )
    if recoil is not None and v_in is not None and v_out is not None:
        omega = expected_recoil(v_in, v_out, q_m, moi_kgm2, ball_mass_kg)
        dev = recoil.omega_rad_s / omega - 1.0
        if abs(dev) > limits.recoil_tolerance_rel:
            out.append(
                Invalidity(
                    Code.RECOIL_MISMATCH,
                    f"Bat recoil {recoil.omega_rad_s:.3f} rad/s vs {omega:.3f} rad/s expected from "
                    f"the ball's momentum ({dev:+.1%}; limit +-{limits.recoil_tolerance_rel:.0%}): "
                    "check the clamp, Q and I.",
                    measured=dev,
                    limit=limits.recoil_tolerance_rel,
                )
            )
    return out


def _pass_notes(passes: GatePasses, limits: ValidityLimits) -> list[Invalidity]:
    out: list[Invalidity] = []
    if passes.extra:
        which = ", ".join(f"gate {c.gate} tick {c.tick}" for c in passes.extra)
        out.append(
            Invalidity(
                Code.DOUBLE_TRIGGER,
                f"Extra crossings set aside ({which}).",
                invalidates=limits.double_trigger_invalidates,
                measured=float(len(passes.extra)),
            )
        )
    missing_in = [g for g in (1, 2, 3) if g not in passes.inbound]
    if passes.inbound and missing_in:
        out.append(
            Invalidity(
                Code.MISSED_GATE,
                f"Inbound ball not seen at gate(s) {missing_in}.",
                invalidates=limits.require_inbound_cross_check,
            )
        )
    # A rebound that stops short of the far gates is normal; a hole before a gate it reached is not.
    if passes.rebound:
        farthest = min(passes.rebound)
        missing_out = [g for g in (3, 2, 1) if g > farthest and g not in passes.rebound]
        if missing_out:
            out.append(
                Invalidity(
                    Code.MISSED_GATE,
                    f"Rebound ball not seen at gate(s) {missing_out} though it reached gate {farthest}.",
                    invalidates=False,
                )
            )
    return out


def is_valid(reasons: list[Invalidity]) -> bool:
    """True when no reason voids the shot (notes alone do not)."""
    return not any(r.invalidates for r in reasons)
