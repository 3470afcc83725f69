"""Air drag on the ball between the gates and the bat: speeds at the impact point, and moist air's density.

Quadratic drag along the line with no other force gives v(s) = v0 exp(-kappa s) after a path s,
kappa = rho Cd A / (2 m). The transit time of a gate pair then fixes the speed at the impact
point exactly (no midpoint approximation). With x the distance from the impact point:

    inbound  (speed V at x = 0, faster farther out):  t_ab = (e^{-kappa x_b} - e^{-kappa x_a}) / (kappa V)
    rebound  (speed V leaving x = 0):                  t_cd = (e^{kappa x_d} - e^{kappa x_c}) / (kappa V)

Written with phi(z) = (1 - e^{-z})/z so that kappa = 0 (no drag) is the plain spacing / time. The
functions are numpy-vectorized and complex-safe (the budget differentiates them by complex step).
Air density: the ideal-gas mixture of dry air and water vapour, with the Magnus form of the
saturation vapour pressure (docs/measurement.md, section 3.6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import overload

import numpy as np

R_DRY = 287.058  # J/(kg K), specific gas constant of dry air
RATIO_VAPOUR = 0.378  # 1 - M_water/M_dry_air
STANDARD_PRESSURE_KPA = 101.325
_SMALL_Z = 1e-4  # below it phi's series (error z^3/24 < 5e-14) replaces the quotient


def phi(z: np.ndarray | complex | float) -> np.ndarray:
    """(1 - exp(-z)) / z, equal to 1 at z = 0; complex-safe, no branch on the value's path."""
    z = np.asarray(z)
    small = np.abs(z) < _SMALL_Z
    safe = np.where(small, 1.0, z)
    series = 1.0 - z / 2.0 + z * z / 6.0
    return np.where(small, series, -np.expm1(-safe) / safe)


def kappa(
    rho: float | np.ndarray, cd: float | np.ndarray, diameter_m: float, mass_kg: float | np.ndarray
) -> np.ndarray:
    """Drag constant rho Cd A / (2 m), 1/m, for a sphere of this diameter and mass."""
    area = math.pi * diameter_m * diameter_m / 4.0
    out: np.ndarray = np.asarray(rho) * np.asarray(cd) * area / (2.0 * np.asarray(mass_kg))
    return out


def inbound_impact_speed(
    x_far: np.ndarray | float, x_near: np.ndarray | float, dt: np.ndarray | float, k: np.ndarray | float
) -> np.ndarray:
    """Speed at the impact point of a ball that crossed x_far then x_near (m from it) dt apart."""
    span = np.asarray(x_far) - np.asarray(x_near)
    speed: np.ndarray = span / np.asarray(dt) * np.exp(-np.asarray(k) * x_near) * phi(np.asarray(k) * span)
    return speed


def rebound_impact_speed(
    x_near: np.ndarray | float, x_far: np.ndarray | float, dt: np.ndarray | float, k: np.ndarray | float
) -> np.ndarray:
    """Speed leaving the impact point of a ball that crossed x_near then x_far dt apart."""
    span = np.asarray(x_far) - np.asarray(x_near)
    speed: np.ndarray = span / np.asarray(dt) * np.exp(np.asarray(k) * x_near) * phi(-np.asarray(k) * span)
    return speed


def saturation_pressure_kpa(t_c: float | complex) -> float | complex:
    """Saturation vapour pressure over water, kPa (Magnus form, Alduchov and Eskridge 1996)."""
    kpa: float | complex = 0.61094 * np.exp(17.625 * t_c / (t_c + 243.04))
    return kpa


@overload
def air_density(t_c: float, rh_pct: float, p_kpa: float) -> float: ...
@overload
def air_density(t_c: complex, rh_pct: complex, p_kpa: complex) -> complex: ...  # complex-step derivatives
def air_density(t_c: float | complex, rh_pct: float | complex, p_kpa: float | complex) -> float | complex:
    """Density of moist air, kg/m^3: (p - 0.378 e) / (R_d T), e = RH e_s(T)."""
    e = rh_pct / 100.0 * saturation_pressure_kpa(t_c)
    return (p_kpa - RATIO_VAPOUR * e) * 1000.0 / (R_DRY * (t_c + 273.15))


@dataclass(frozen=True)
class AirDensity:
    """The lab air's density and its standard uncertainty from those of its inputs (GUM)."""

    rho: float
    u: float
    temperature_c: float
    humidity_pct: float
    pressure_kpa: float
    contributions: dict[str, float]  # u of rho due to each input, kg/m^3

    def as_dict(self) -> dict[str, object]:
        """Plain values for the record."""
        return {
            "rho_kgm3": self.rho,
            "u_kgm3": self.u,
            "temperature_c": self.temperature_c,
            "humidity_pct": self.humidity_pct,
            "pressure_kpa": self.pressure_kpa,
            "contributions": dict(self.contributions),
        }


FORMULA_U_REL = 5e-4  # covers this formula against CIPM-2007: <= 4.6e-4 at 15-27 C, 20-80 % RH (tested)


def lab_air(
    t_c: float, rh_pct: float, p_kpa: float, u_t_c: float, u_rh_pct: float, u_p_kpa: float
) -> AirDensity:
    """Air density with u from temperature, humidity, pressure and the formula itself."""
    h = 1e-30
    rho = float(air_density(t_c, rh_pct, p_kpa))
    sens = {
        "temperature": float(np.imag(air_density(t_c + 1j * h, rh_pct, p_kpa)) / h) * u_t_c,
        "humidity": float(np.imag(air_density(t_c, rh_pct + 1j * h, p_kpa)) / h) * u_rh_pct,
        "pressure": float(np.imag(air_density(t_c, rh_pct, p_kpa + 1j * h)) / h) * u_p_kpa,
        "formula": rho * FORMULA_U_REL,
    }
    contributions = {k: abs(v) for k, v in sens.items()}
    u = math.sqrt(sum(v * v for v in contributions.values()))
    return AirDensity(rho, u, t_c, rh_pct, p_kpa, contributions)
