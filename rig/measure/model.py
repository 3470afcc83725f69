"""The measurement model of one hit: raw inputs, their distributions, and the function to results.

Per hit:
    v_in  = (x_a - x_b) / ((t_b - d_b) - (t_a - d_a))      inbound pair a -> b
    v_out = (x_d - x_c) / ((t_d - d_d) - (t_c - d_c))      rebound pair c -> d
    e_A = v_out / v_in,  BBCOR = e_A (1 + k) + k with k = m Q^2 / I,  BESR = e_A + 1/2
t: crossing times (random per hit), x: gate positions, d: gate trigger delays, Q, I, m, and the
drag correction's Cd (inbound, rebound) and air density rho (systematic: shared by every hit on
one bat). With drag the pair speeds become speeds at the impact point (rig.measure.drag): the
plain spacing / time above when Cd or rho is 0. rig.measure.uncertainty propagates it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from rig.core.devices import GateConfig, GateCrossing
from rig.core.units import INCH
from rig.measure.drag import inbound_impact_speed, kappa, phi, rebound_impact_speed
from rig.measure.speeds import GatePasses, ShotDataError, elapsed_s

OUTPUTS = ("v_in", "v_out", "e_a", "bbcor", "besr")
SHARED = ("x1", "x2", "x3", "delay_g1", "delay_g2", "delay_g3", "Q", "I", "m_ball", "Cd_in", "Cd_out", "rho")
BALL_DIAMETER_M = 0.0737  # 2.9 in


class Spread(BaseModel):
    """An input's distribution: `width` is the standard deviation (normal) or half-width (rectangular)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    width: float = Field(ge=0.0)
    shape: Literal["normal", "rectangular"] = "normal"

    @property
    def standard(self) -> float:
        """Standard uncertainty (GUM): sigma, or half-width / sqrt(3)."""
        return self.width if self.shape == "normal" else self.width / math.sqrt(3.0)

    def sample(self, rng: np.random.Generator, size: tuple[int, ...]) -> np.ndarray:
        """Zero-mean draws from this distribution."""
        if self.shape == "normal":
            return rng.normal(0.0, self.width, size)
        return rng.uniform(-self.width, self.width, size)


class UncertaintyModel(BaseModel):
    """Input distributions; defaults marked [assumed] in docs/measurement.md are not from a source."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    trigger_jitter: Spread = Spread(width=1e-6)  # s per crossing, random [assumed]
    gate_delay: Spread = Spread(width=0.0)  # s per gate channel, systematic [assumed 0: calibrate]
    gate_position: Spread = Spread(width=0.005 * INCH, shape="rectangular")  # NCAA +-0.005 in
    impact_q: Spread = Spread(width=0.001, shape="rectangular")  # m, stage setting [assumed]
    moi_relative: Spread = Spread(width=0.005)  # u(I)/I (docs/standards.md: measure I to 0.5 %)
    ball_mass: Spread = Spread(width=0.0005, shape="rectangular")  # kg, weighed ball [assumed]
    drag_in: Spread = Spread(width=0.05)  # Cd of the inbound ball (rig config air table)
    drag_out: Spread = Spread(width=0.1)  # Cd of the rebounding ball
    air_density: Spread = Spread(width=0.04)  # kg/m^3, lab air (rig.measure.drag.lab_air)
    coverage_k: float = Field(2.0, gt=0.0)


DEFAULT_MODEL = UncertaintyModel()


@dataclass(frozen=True)
class ShotInputs:
    """One hit's raw inputs: the four crossing times used (s, from the first), geometry, bat, ball."""

    times_s: tuple[float, float, float, float]  # inbound a, inbound b, rebound c, rebound d
    gates: tuple[int, int, int, int]  # gate of each time, e.g. (2, 3, 3, 2)
    positions_m: tuple[float, float, float]
    q_m: float
    moi_kgm2: float
    ball_mass_kg: float
    tick_s: float
    cd_in: float = 0.0  # drag coefficients and air density: 0 means no drag correction
    cd_out: float = 0.0
    air_density: float = 0.0
    ball_diameter_m: float = BALL_DIAMETER_M

    def __post_init__(self) -> None:
        ga, gb, gc, gd = self.gates
        t = self.times_s
        x1, x2, x3 = self.positions_m
        if not (all(1 <= g <= 3 for g in self.gates) and ga < gb and gc > gd):
            raise ShotDataError(f"gates {self.gates}: inbound must rise, rebound fall, within 1..3")
        if not x1 > x2 > x3 >= 0.0:
            raise ShotDataError(f"gate positions {self.positions_m} must be three, farthest first, >= 0")
        if not (math.isfinite(sum(t)) and t[1] > t[0] and t[3] > t[2]):
            raise ShotDataError(f"crossing times {t} give no speed: each pair needs a later second time")
        values = (self.q_m, self.moi_kgm2, self.ball_mass_kg, self.tick_s)
        if not all(math.isfinite(v) and v > 0.0 for v in values):
            raise ShotDataError(f"Q, I, ball mass and tick must be finite and > 0, not {values}")
        drag = (self.cd_in, self.cd_out, self.air_density)
        if not (all(math.isfinite(v) and v >= 0.0 for v in drag) and 0.0 < self.ball_diameter_m < 1.0):
            raise ShotDataError(f"Cd, air density must be finite and >= 0, not {drag}")

    @classmethod
    def recorded(cls, inputs: Mapping[str, Any] | None) -> ShotInputs:
        """A hit's inputs from its record (ShotOutcome.inputs: JSON has lists where these are tuples)."""
        if inputs is None:
            raise ShotDataError("a valid hit without its recorded inputs: a damaged record")
        fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in inputs.items()}
        return cls(**fields)

    @classmethod
    def ideal(
        cls,
        v_in: float,
        v_out: float,
        positions_m: Sequence[float],
        tick_s: float,
        q_m: float,
        moi_kgm2: float,
        ball_mass_kg: float,
        gates: tuple[int, int, int, int] = (2, 3, 3, 2),
        cd_in: float = 0.0,
        cd_out: float = 0.0,
        air_density: float = 0.0,
    ) -> ShotInputs:
        """The crossing times of a shot at these impact-point speeds (straight line without drag)."""
        if not (v_in > 0.0 and v_out > 0.0):
            raise ShotDataError(f"speeds must be > 0, not v_in={v_in}, v_out={v_out}")
        x = tuple(float(p) for p in positions_m)
        k_in = float(kappa(air_density, cd_in, BALL_DIAMETER_M, ball_mass_kg))
        k_out = float(kappa(air_density, cd_out, BALL_DIAMETER_M, ball_mass_kg))

        def t_in(d: float) -> float:  # from d m out to the impact point
            return d * float(phi(k_in * d)) / v_in

        def t_out(d: float) -> float:  # from the impact point d m out
            return d * float(phi(-k_out * d)) / v_out

        ga, gb, gc, gd = gates
        t_hit = t_in(x[ga - 1])
        times = (0.0, t_hit - t_in(x[gb - 1]), t_hit + t_out(x[gc - 1]), t_hit + t_out(x[gd - 1]))
        return cls(
            times, gates, (x[0], x[1], x[2]), q_m, moi_kgm2, ball_mass_kg, tick_s, cd_in, cd_out, air_density
        )

    @classmethod
    def from_passes(
        cls,
        passes: GatePasses,
        positions_m: Sequence[float],
        cfg: GateConfig,
        q_m: float,
        moi_kgm2: float,
        ball_mass_kg: float,
        drag: tuple[float, float, float, float] = (0.0, 0.0, 0.0, BALL_DIAMETER_M),
    ) -> ShotInputs:
        """The crossings ShotSpeeds.inbound and .rebound use (same pair choice), as times.

        `drag` is (Cd inbound, Cd rebound, air density, ball diameter); zeros: no correction.
        """
        a, b = _pair_used(passes.inbound, inbound=True)
        c, d = _pair_used(passes.rebound, inbound=False)
        times = (0.0, elapsed_s(a, b, cfg), elapsed_s(a, c, cfg), elapsed_s(a, d, cfg))
        gates = (a.gate, b.gate, c.gate, d.gate)
        x = tuple(float(p) for p in positions_m)
        return cls(times, gates, (x[0], x[1], x[2]), q_m, moi_kgm2, ball_mass_kg, cfg.tick_s, *drag)

    def vector(self) -> np.ndarray:
        """Input vector: 4 times, x1..x3, 3 gate delays (nominal 0), Q, I, m, Cd_in, Cd_out, rho."""
        return np.array(
            [
                *self.times_s,
                *self.positions_m,
                0.0,
                0.0,
                0.0,
                self.q_m,
                self.moi_kgm2,
                self.ball_mass_kg,
                self.cd_in,
                self.cd_out,
                self.air_density,
            ]
        )

    def names(self) -> tuple[str, ...]:
        """Names of the inputs in vector() order."""
        ga, gb, gc, gd = self.gates
        return (f"t_in_g{ga}", f"t_in_g{gb}", f"t_out_g{gc}", f"t_out_g{gd}", *SHARED)

    def shared(self) -> tuple[float, ...]:
        """The systematic inputs' values, which every hit on one bat must share."""
        return (*self.positions_m, self.q_m, self.moi_kgm2, self.ball_mass_kg)


def _pair_used(p: dict[int, GateCrossing], inbound: bool) -> tuple[GateCrossing, GateCrossing]:
    # Mirrors ShotSpeeds.inbound/.rebound: near pair, else the span if gate 2 missed, else far.
    if 2 in p and 3 in p:
        lo, hi = 2, 3
    elif 2 not in p and 1 in p and 3 in p:
        lo, hi = 1, 3
    elif 1 in p and 2 in p:
        lo, hi = 1, 2
    else:
        raise ShotDataError(f"{'inbound' if inbound else 'rebound'} pass has no gate pair: gates {sorted(p)}")
    return (p[lo], p[hi]) if inbound else (p[hi], p[lo])


def inbound_at_impact(
    passes: GatePasses,
    positions_m: Sequence[float],
    cfg: GateConfig,
    ball_mass_kg: float,
    drag: tuple[float, float, float, float],
) -> float:
    """The inbound speed at the impact point from the pair ShotSpeeds.inbound uses, drag corrected.

    Needs no rebound, so a shot's speed can be held to the target before its metrics exist.
    """
    a, b = _pair_used(passes.inbound, inbound=True)
    cd_in, _, rho, diameter = drag
    k = kappa(rho, cd_in, diameter, ball_mass_kg)
    v = inbound_impact_speed(positions_m[a.gate - 1], positions_m[b.gate - 1], elapsed_s(a, b, cfg), k)
    return float(v)


def outputs(
    p: np.ndarray, gates: tuple[int, int, int, int], ball_diameter_m: float = BALL_DIAMETER_M
) -> np.ndarray:
    """The measurement function, vectorized over leading axes (complex-safe: no abs, no branches)."""
    ga, gb, gc, gd = (g - 1 for g in gates)
    t, x, d = p[..., 0:4], p[..., 4:7], p[..., 7:10]
    q, moi, m = p[..., 10], p[..., 11], p[..., 12]
    k_in = kappa(p[..., 15], p[..., 13], ball_diameter_m, m)
    k_out = kappa(p[..., 15], p[..., 14], ball_diameter_m, m)
    dt_in = (t[..., 1] - d[..., gb]) - (t[..., 0] - d[..., ga])
    dt_out = (t[..., 3] - d[..., gd]) - (t[..., 2] - d[..., gc])
    v_in = inbound_impact_speed(x[..., ga], x[..., gb], dt_in, k_in)
    v_out = rebound_impact_speed(x[..., gc], x[..., gd], dt_out, k_out)
    e = v_out / v_in
    k = m * q**2 / moi
    return np.stack([v_in, v_out, e, e * (1.0 + k) + k, e + 0.5], axis=-1)


def values_and_jacobian(shot: ShotInputs) -> tuple[np.ndarray, np.ndarray]:
    """The outputs and d(outputs)/d(inputs), 5 x 16, by complex step (h = 1e-30: exact to rounding).

    With h = 1e-30 the real part of every perturbed evaluation is the unperturbed value.
    """
    h = 1e-30
    p = shot.vector()
    y = outputs(p + 1j * h * np.eye(p.size), shot.gates, shot.ball_diameter_m)
    return y[0].real.copy(), (y.imag / h).T


def jacobian(shot: ShotInputs) -> np.ndarray:
    """d(outputs)/d(inputs), 5 x 16, by complex step."""
    return values_and_jacobian(shot)[1]


def input_u(shot: ShotInputs, model: UncertaintyModel) -> np.ndarray:
    u_t = np.hypot(shot.tick_s / np.sqrt(12.0), model.trigger_jitter.standard)
    return np.array(
        [u_t] * 4
        + [model.gate_position.standard] * 3
        + [model.gate_delay.standard] * 3
        + [model.impact_q.standard, model.moi_relative.standard * shot.moi_kgm2, model.ball_mass.standard]
        + [model.drag_in.standard, model.drag_out.standard, model.air_density.standard]
    )
