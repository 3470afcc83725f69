"""The simulator's default physics: what the world uses for a slot no effect of the scene fills.

Straight-line flight in closed form, a rigid barrel (solved once per distinct impact and cached),
counter ticks by rounding, nominal lab air. Effects in `rig.simulators.effects` replace these.
"""

from __future__ import annotations

import math
from typing import Protocol

from rig.core.units import G_STANDARD
from rig.physics import CollisionParams, Impact, PivotedBat, predict_bat, solve

NOMINAL_TEMP_C = 21.0
NOMINAL_RH_PCT = 50.0


class Flight(Protocol):
    """The ball's flight along the line of fire from a given speed."""

    def time_to(self, distance: float, speed: float) -> float:
        """Seconds to cover `distance` m starting at `speed` m/s."""
        ...

    def speed_at(self, distance: float, speed: float) -> float:
        """Speed after covering `distance` m starting at `speed` m/s."""
        ...


class Collision(Protocol):
    """The ball-bat impact: apparent COR e_A and contact time."""

    def collide(self, params: CollisionParams, speed: float, q: float) -> tuple[float, float]:
        """(e_A, contact time in s) for a ball at `speed` m/s striking `q` m from the pivot."""
        ...


class Ticks(Protocol):
    """How the counter latches a beam break."""

    def latch(self, gate: int, time_s: float) -> int:
        """Ticks counted from the world's start to the latch of this beam break (unwrapped)."""
        ...


class RecoilSensor(Protocol):
    """The pivot encoder's peak angular speed after an impact."""

    def recoil(self, m_ball: float, q: float, v_in: float, v_out: float) -> float:
        """Peak angular speed of the bat about the pivot, rad/s."""
        ...


class EnvironmentSensor(Protocol):
    """The lab's temperature and humidity sensors."""

    def environment(self, time_s: float) -> tuple[float, float]:
        """(temperature in C, relative humidity in %) at virtual time `time_s`."""
        ...


class StraightFlight:
    """No drag: constant speed along a straight line."""

    def time_to(self, distance: float, speed: float) -> float:
        """distance / speed."""
        return distance / speed

    def speed_at(self, distance: float, speed: float) -> float:
        """The speed is unchanged."""
        return speed


RIGID_RTOL = 1e-12  # as rig.physics.rigid_cor, so the simulated truth is that function's value
CACHE_SIZE = 256  # distinct impacts remembered; scatter makes every shot distinct, so bound it


class SolveCache:
    """The last CACHE_SIZE collision solves, keyed by (ball constants, speed, impact point)."""

    def __init__(self) -> None:
        self._solved: dict[tuple[CollisionParams, float, float], tuple[float, float]] = {}

    def get(self, key: tuple[CollisionParams, float, float]) -> tuple[float, float] | None:
        """The cached (e_A, contact time), or None."""
        return self._solved.get(key)

    def put(self, key: tuple[CollisionParams, float, float], value: tuple[float, float]) -> None:
        """Remember a solve, forgetting the oldest beyond CACHE_SIZE."""
        if len(self._solved) >= CACHE_SIZE:
            del self._solved[next(iter(self._solved))]
        self._solved[key] = value


class RigidCollision:
    """Rigid barrel on the pivoted bat (predict_bat with hoop_hz=None), one solve per distinct impact."""

    def __init__(self, moi_kgm2: float) -> None:
        self.moi_kgm2 = moi_kgm2
        self._cache = SolveCache()

    def collide(self, params: CollisionParams, speed: float, q: float) -> tuple[float, float]:
        """(e_A, contact time); repeated shots at the same speed and place reuse the solve."""
        key = (params, speed, q)
        hit = self._cache.get(key)
        if hit is None:
            hit = solve_pivoted(params, speed, None, self.moi_kgm2, q)
            self._cache.put(key, hit)
        return hit


class RigidTarget:
    """A rigid target in the clamp (cylinder or plate): the model's rigid-surface COR, no recoil.

    rig.physics.rigid_cor is the ball on a rigid clamped barrel (the founding paper's CCOR model);
    on a plate the ball's k1 is scaled by the scene's contact factor. One solve per distinct impact.
    """

    def __init__(self, contact_factor: float = 1.0) -> None:
        self.contact_factor = contact_factor
        self._cache = SolveCache()

    def surface(self, params: CollisionParams) -> CollisionParams:
        """The ball's constants against this surface."""
        if self.contact_factor == 1.0:
            return params
        return params.model_copy(update={"k1": params.k1 * self.contact_factor})

    def collide(self, params: CollisionParams, speed: float, q: float) -> tuple[float, float]:
        """(COR, contact time); the impact point does not matter on a fixed rigid target."""
        key = (params, speed, 0.0)
        hit = self._cache.get(key)
        if hit is None:
            result = solve(Impact(self.surface(params), speed), rtol=RIGID_RTOL)
            hit = (result.cor, result.contact_time_s)
            self._cache.put(key, hit)
        return hit


def solve_pivoted(
    params: CollisionParams, speed: float, hoop_hz: float | None, moi_kgm2: float, q: float
) -> tuple[float, float]:
    """(e_A, contact time) of rig.physics' pivoted-bat model."""
    pred = predict_bat(params, speed, hoop_hz, PivotedBat(moi_kgm2=moi_kgm2, impact_from_pivot_m=q))
    return pred.e_a, pred.contact_time_s


class RoundingTicks:
    """An ideal counter: the beam break's time rounded to the nearest tick."""

    def __init__(self, tick_s: float) -> None:
        self.tick_s = tick_s

    def latch(self, gate: int, time_s: float) -> int:
        """round(t / tick)."""
        return round(time_s / self.tick_s)


class NominalEnvironment:
    """Lab sensors without the environment effect: fixed nominal readings."""

    def environment(self, time_s: float) -> tuple[float, float]:
        """Always 21 C and 50 % RH."""
        return NOMINAL_TEMP_C, NOMINAL_RH_PCT


def pendulum_period(moi_kgm2: float, mass_kg: float, pivot_to_cg_m: float, amplitude_rad: float) -> float:
    """Period of the bat swinging on the pivot: T0 = 2 pi sqrt(I/(m g d)), times (1 + theta0^2/16)."""
    t0 = 2.0 * math.pi * math.sqrt(moi_kgm2 / (mass_kg * G_STANDARD * pivot_to_cg_m))
    # First-order finite-amplitude correction that ASTM F2398 users back out (docs/standards.md, 2).
    return t0 * (1.0 + amplitude_rad**2 / 16.0)


def drop_m(seconds: float) -> float:
    """How far the ball has fallen `seconds` after leaving the bat (it leaves horizontally)."""
    return 0.5 * G_STANDARD * seconds * seconds
