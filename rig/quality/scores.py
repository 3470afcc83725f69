"""Comparison scores of ISO 13528 (ISO/IEC 17025 7.7.1 and 7.7.2): E_n, z and a robust sigma_pt.

E_n = (x - X) / sqrt(U_x^2 + U_X^2), with both results' expanded uncertainties: |E_n| <= 1 is
satisfactory. z = (x - X) / sigma_pt: |z| <= 2 satisfactory, 2 < |z| < 3 questionable, |z| >= 3
unsatisfactory. sigma_pt is the user's, or the robust standard deviation s* of the differences
x - X by ISO 13528's Algorithm A (started from the median and the scaled MAD, 1.483 median|x - x*|).
Pure: numbers in, numbers out; a value that cannot be scored raises ParameterError naming it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rig.core.errors import ParameterError

Assessment = Literal["satisfactory", "questionable", "unsatisfactory"]

EN_LIMIT = 1.0  # |E_n| <= 1 satisfactory (ISO 13528)
Z_WARNING = 2.0  # |z| <= 2 satisfactory
Z_ACTION = 3.0  # |z| >= 3 unsatisfactory
# Fewer differences than this give no robust sigma_pt: the standard's own minimum was not read
# [assumed]; with fewer, give sigma_pt yourself.
MIN_ROBUST = 8
MAD_SCALE = 1.483  # Algorithm A's start: s* = 1.483 median |x_i - x*| (the scaled MAD)
CLIP = 1.5  # delta = 1.5 s*
SD_SCALE = 1.134  # s* = 1.134 sqrt(sum (x_i* - x*)^2 / (p - 1)): corrects the clipping
_MAX_ITERATIONS = 1000
_TOLERANCE = 1e-12  # relative; the standard's third significant figure is looser


def _finite(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ParameterError(name, value, "must be a finite number")
    return float(value)


def _positive(name: str, value: float) -> float:
    if _finite(name, value) <= 0.0:
        raise ParameterError(name, value, "must be greater than zero")
    return float(value)


def en_score(x: float, u_x: float, ref: float, u_ref: float) -> float:
    """E_n = (x - X) / sqrt(U_x^2 + U_X^2), both U expanded (k = 2 as certificates give them)."""
    x, ref = _finite("x", x), _finite("X", ref)
    u_x, u_ref = _positive("U_x", u_x), _positive("U_X", u_ref)
    return (x - ref) / math.hypot(u_x, u_ref)


def z_score(x: float, ref: float, sigma_pt: float) -> float:
    """z = (x - X) / sigma_pt."""
    return (_finite("x", x) - _finite("X", ref)) / _positive("sigma_pt", sigma_pt)


def assess_en(en: float) -> Assessment:
    """|E_n| <= 1: satisfactory; otherwise unsatisfactory (E_n has no questionable band)."""
    return "satisfactory" if abs(_finite("E_n", en)) <= EN_LIMIT else "unsatisfactory"


def assess_z(z: float) -> Assessment:
    """|z| <= 2 satisfactory, 2 < |z| < 3 questionable, |z| >= 3 unsatisfactory."""
    size = abs(_finite("z", z))
    if size <= Z_WARNING:
        return "satisfactory"
    return "questionable" if size < Z_ACTION else "unsatisfactory"


@dataclass(frozen=True)
class Robust:
    """Algorithm A's robust average x* and standard deviation s* of p values, and its iterations."""

    mean: float
    sd: float
    p: int
    iterations: int


def algorithm_a(values: Sequence[float], name: str = "differences") -> Robust:
    """ISO 13528 Algorithm A: x*, s* from the median and scaled MAD, then values clipped at
    x* +- 1.5 s* and x* = mean, s* = 1.134 SD of the clipped values, until neither changes."""
    data = np.array([_finite(name, v) for v in values], dtype=float)
    if data.size < MIN_ROBUST:
        raise ParameterError(
            name, f"{data.size} values", f"a robust sigma_pt needs at least {MIN_ROBUST}: give --sigma-pt"
        )
    mean = float(np.median(data))
    sd = MAD_SCALE * float(np.median(np.abs(data - mean)))
    if sd == 0.0:
        raise ParameterError(
            name, f"{data.size} values", "half or more are equal, so their spread is zero: give --sigma-pt"
        )
    for iteration in range(1, _MAX_ITERATIONS + 1):
        delta = CLIP * sd
        clipped = np.clip(data, mean - delta, mean + delta)
        new_mean = float(np.mean(clipped))
        new_sd = SD_SCALE * float(np.std(clipped, ddof=1))
        done = abs(new_mean - mean) <= _TOLERANCE * new_sd and abs(new_sd - sd) <= _TOLERANCE * new_sd
        mean, sd = new_mean, new_sd
        if done:
            return Robust(mean, sd, int(data.size), iteration)
    return Robust(mean, sd, int(data.size), _MAX_ITERATIONS)


@dataclass(frozen=True)
class Score:
    """One bat's comparison: the difference x - X, E_n and z with their assessments."""

    difference: float
    en: float
    en_assessment: Assessment
    z: float | None
    z_assessment: Assessment | None


def score(x: float, u_x: float, ref: float, u_ref: float, sigma_pt: float | None) -> Score:
    """E_n of two results with their U, and z when a sigma_pt is known."""
    en = en_score(x, u_x, ref, u_ref)
    z = None if sigma_pt is None else z_score(x, ref, sigma_pt)
    return Score(x - ref, en, assess_en(en), z, None if z is None else assess_z(z))
