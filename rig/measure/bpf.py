"""Bat performance factor (BPF): the pivoted bat's BBCOR over the ball's COR against a rigid wall.

BPF = BBCOR / ball COR [C] (WSU SSL glossary; Brandt): how much faster a ball rebounds from the bat
than from a rigid flat wall, both at 60 mph [C] (NCAA News 1997; ASTM F1887 for the ball). A rigid
wall has BPF = 1.00. The limits: USSSA baseball 1.15, NSA/USSSA fastpitch 1.20 [C2].

Two bases must not be mixed [C]: ASTM F1890-23 (BPF) takes the bat as **pivoted** (the rig's clamp
constraint kept: BBCOR = e_A (1 + k) + k, k = m Q^2 / I_pivot), F2219-23 (BBCOR, BBS) takes it as
**unconstrained** (a free bat: the recoil factor r = m (1/M + b^2 / I_cm), b the impact's distance
from the centre of mass). For one measured e_A the two differ unless Q is the centre of percussion
about the pivot. Every BPF here is on the pivoted basis; `bbcor_unconstrained` is F2219-23's, for
comparison only.

The ball COR is one value of the lot (its ball-cor test) divided into every hit: its uncertainty is
fully correlated across the hits and does not average down (`bpf_u`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rig.core.units import MPH

BPF_SPEED_M_S = 60.0 * MPH  # [C] 60 mph at the bat, as the ball's COR test at the wall
PIVOTED = "pivoted: BBCOR = e_A (1 + k) + k, k = m Q^2 / I_pivot"
F1890 = "ASTM F1890-23's basis"  # the BPF procedures' citation, not the NCAA BBCOR's
UNCONSTRAINED = "unconstrained (ASTM F2219-23): BBCOR = e_A (1 + r) + r, r = m (1/M + b^2 / I_cm)"


@dataclass(frozen=True)
class BpfStandard:
    """One body's BPF limit: its metric's name, who sets it, the limit and the ball it is tested with."""

    name: str  # the registry's metric name
    body: str
    limit: float  # [C2]
    ball: str  # the ball the body's bats are tested with [U]


STANDARDS: tuple[BpfStandard, ...] = (
    BpfStandard("usssa_bpf", "USSSA baseball", 1.15, "baseball"),
    BpfStandard("fastpitch_bpf", "NSA/USSSA fastpitch", 1.20, "11 in fastpitch softball"),
)


def bbcor_pivoted(e_a: float, k: float) -> float:
    """BBCOR of the pivoted bat (F1890's basis): e_A (1 + k) + k."""
    return e_a * (1.0 + k) + k


def unconstrained_recoil(m_ball: float, bat_mass: float, i_cm: float, b: float) -> float:
    """r = m (1/M + b^2 / I_cm): the free bat's recoil factor at b m from its centre of mass."""
    return m_ball * (1.0 / bat_mass + b * b / i_cm)


def bbcor_unconstrained(
    e_a: float, m_ball: float, bat_mass: float, moi_pivot: float, pivot_to_cm: float, q: float
) -> float:
    """F2219-23's basis: BBCOR = e_A (1 + r) + r of the free bat, from the pivoted bat's MOI
    (I_cm = I_pivot - M d^2, d the pivot-to-centre-of-mass distance; b = Q - d)."""
    i_cm = moi_pivot - bat_mass * pivot_to_cm**2
    if i_cm <= 0.0:
        raise ValueError(f"I_pivot {moi_pivot:g} is below M d^2 {bat_mass * pivot_to_cm**2:g}")
    r = unconstrained_recoil(m_ball, bat_mass, i_cm, q - pivot_to_cm)
    return e_a * (1.0 + r) + r


def bpf(bbcor: float, ball_cor: float) -> float:
    """BPF = BBCOR / ball COR."""
    if not ball_cor > 0.0:
        raise ValueError(f"ball COR {ball_cor!r} must be positive")
    return bbcor / ball_cor


@dataclass(frozen=True)
class BpfUncertainty:
    """BPF's standard uncertainty and its two parts (k = 1)."""

    u: float
    from_bbcor: float  # u(mean BBCOR) / COR: the hits' own, averaged as they are
    from_ball_cor: float  # BPF u(COR) / COR: one lot value in every hit, not averaged down


def bpf_u(bpf_mean: float, u_bbcor_mean: float, ball_cor: float, u_ball_cor: float) -> BpfUncertainty:
    """u(BPF) for BPF = mean BBCOR / COR: u^2 = (u(mean BBCOR)/COR)^2 + (BPF u(COR)/COR)^2.

    The COR's term is that of the mean: the same COR divides every hit, so its error is fully
    correlated across them (sum of n equal terms over n), never divided by sqrt(n)."""
    a = u_bbcor_mean / ball_cor
    b = abs(bpf_mean) * u_ball_cor / ball_cor
    return BpfUncertainty(math.hypot(a, b), a, b)


def shared_u(
    g: float,
    bpf_mean: float,
    ball_cor: float,
    d_hits: tuple[float, ...],
    d_cor: tuple[float, ...],
    cov: tuple[tuple[float, ...], ...],
) -> float:
    """u(BPF) from ball sensitivities s shared by the hits' BBCOR and the lot's COR.

    The hits' mean BBCOR moves by g s.d_hits and the COR by s.d_cor (d: each one's mean offset from
    the lot's nominal ball, e.g. its air's (C, % RH) or its hits before), so BPF = BBCOR / COR moves
    by s.a with a = (g d_hits - BPF d_cor) / COR: u^2 = a' Cov(s) a. The two offsets' terms are one
    error, not two: they add when the offsets differ in sign and cancel when they agree, which
    combining them in quadrature would not see."""
    a = [(g * h - bpf_mean * c) / ball_cor for h, c in zip(d_hits, d_cor, strict=True)]
    var = sum(a[i] * cov[i][j] * a[j] for i in range(len(a)) for j in range(len(a)))
    return math.sqrt(max(0.0, var))
