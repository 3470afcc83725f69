"""Validated parameters of the ball-barrel collision model (founding paper, Eqs. 1-2).

The contact force of the ball on the barrel is F = k1 d|d|^a + c1 d'|d|^b with d = x1 - x2 the
ball's compression. The barrel's hoop mode is a mass m2 on a spring k2 = m2 (2 pi f_hoop)^2 with
damping c2. All values are SI.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.core.errors import ParameterError

Positive = Annotated[float, Field(gt=0.0)]
NonNegative = Annotated[float, Field(ge=0.0)]
Exponent = Annotated[float, Field(ge=0.0, le=1.0)]


class CollisionParams(BaseModel):
    """The model's constants, with the paper's values as defaults."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    m1: Positive = Field(0.145, description="ball mass, kg")
    k1: Positive = Field(60e6, description="ball stiffness coefficient, N/m^(1+a)")
    c1: NonNegative = Field(5000.0, description="ball damping coefficient, N s/m^(1+b)")
    a: Exponent = Field(0.6495, description="stiffness exponent")
    b: Exponent = Field(0.5202, description="damping exponent")
    m2: Positive = Field(0.09, description="effective barrel (hoop-mode) mass, kg")
    c2: NonNegative = Field(100.0, description="barrel damping, N s/m")

    @classmethod
    def build(cls, **values: float) -> CollisionParams:
        """Validate and build; a refused value raises ParameterError naming the parameter."""
        try:
            return cls(**values)
        except ValidationError as exc:
            raise ParameterError.from_validation(exc) from None

    def k2(self, hoop_hz: float) -> float:
        """Barrel spring constant k2 = m2 (2 pi f)^2 for hoop frequency f (Hz)."""
        return barrel_spring(self.m2, check_hoop(hoop_hz))

    def compression_scale(self, speed: float) -> float:
        """Peak compression of an undamped ball on a rigid wall: the model's length scale, m."""
        n = 2.0 + self.a
        return (n * self.m1 * speed * speed / (2.0 * self.k1)) ** (1.0 / n)


DEFAULT_PARAMS = CollisionParams()

# What a real ball and barrel can be, for values a user or a scene file gives (the solver itself
# accepts the wider ranges its hard-case tests explore). A baseball weighs 142-149 g and a softball
# 178-198 g; the paper's stiffness, damping and barrel mass are 60e6, 5000 and 0.09 kg, and the
# ranges leave at least two decades either side of them.
PHYSICAL_RANGES: dict[str, tuple[float, float, str]] = {
    "m1": (0.05, 0.5, "kg"),
    "k1": (1e4, 1e10, "N/m^(1+a)"),
    "c1": (0.0, 1e6, "N s/m^(1+b)"),
    "a": (0.0, 1.0, ""),
    "b": (0.0, 1.0, ""),
    "m2": (1e-3, 1.0, "kg"),
    "c2": (0.0, 1e5, "N s/m"),
}


def check_physical(params: CollisionParams) -> CollisionParams:
    """`params` if every constant lies in PHYSICAL_RANGES; else ParameterError naming the first."""
    for name, (low, high, unit) in PHYSICAL_RANGES.items():
        value = getattr(params, name)
        if not low <= value <= high:
            raise ParameterError(name, value, f"must lie within {low:g}-{high:g} {unit}".rstrip())
    return params


def _check_finite_positive(name: str, value: float, unit: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, value, f"must be a number in {unit}") from None
    if not math.isfinite(x):
        raise ParameterError(name, value, f"must be finite ({unit})")
    if x <= 0.0:
        raise ParameterError(name, value, f"must be greater than 0 {unit}")
    return x


def check_speed(speed: float) -> float:
    """Validate an inbound ball speed in m/s (finite and > 0)."""
    return _check_finite_positive("speed", speed, "m/s")


def check_hoop(hoop_hz: float) -> float:
    """Validate a hoop frequency in Hz (finite and > 0; use the rigid model for infinity)."""
    return _check_finite_positive("hoop_hz", hoop_hz, "Hz")


RTOL_MIN, RTOL_MAX = 1e-13, 1e-2  # the relative tolerances a solver accepts (check_tolerance)


def check_tolerance(rtol: float) -> float:
    """Validate a relative tolerance: between 1e-13 and 1e-2.

    Below ~1e-13 double precision cannot honour the request (scipy silently raises it to
    100 eps), so it is refused rather than reported as met.
    """
    x = _check_finite_positive("rtol", rtol, "(relative)")
    if not RTOL_MIN <= x <= RTOL_MAX:
        raise ParameterError("rtol", rtol, "must lie between 1e-13 and 1e-2")
    return x


def barrel_spring(m2: Any, hoop_hz: Any) -> Any:
    """k2 = m2 (2 pi f)^2, unchecked, for a hoop frequency or an array of them: the one formula
    (CollisionParams.k2, the kernel's parameter vectors; `_dop853.solve_impact` repeats it compiled).
    The square as w * w, as numba and numpy's arrays take it: the C library's pow(w, 2), which
    Python's w ** 2 is, differs from it in the last bit in about 1 case in 1,000."""
    w = 2.0 * math.pi * hoop_hz
    return m2 * (w * w)
