"""The pendulum's period and the bat's recoil computed on the host from a sampled swing angle.

A swing sensor (an angle encoder on the pivot) gives samples (t, angle). Two numbers come from them:

- the **period**: each zero crossing is timed by a straight-line fit to the samples around it (a
  sine is straight near its zero: its curvature vanishes there); the crossing times t_k are fitted
  with t_k = a + (T/2) k + c (-1)^k, so an encoder zero that is off the rest angle (which shifts
  rising and falling crossings in opposite directions) does not bias T;
- the **peak recoil angular speed**: the angle is flat before an impact and rises at the bat's
  angular speed after it; the first sample interval that moves faster than half the fastest one
  holds the step, and a straight-line fit to the `window` samples after it gives the speed.

Each result has its standard uncertainty (GUM, k = 1). Its noise term is the larger of the
encoder's quantization (resolution / sqrt 12, with the time stamps' resolution turned into angle)
and the fits' own residual scatter (pooled over every crossing; for the recoil, pooled with the
flat trace before the step): a trace noisier than its resolution, or a model that fits badly,
shows as residual.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.core.errors import ParameterError

DEFAULT_RECOIL_WINDOW = 8  # samples fitted after the step [assumed]: 4 ms at 2 kHz
Samples = Sequence[float] | np.ndarray
RESOLVED_STEPS = 4.0  # a step is found reliably only if the angle moves this many noise SDs per sample


@dataclass(frozen=True)
class PeriodEstimate:
    """Mean period over `cycles` full swings from `2 cycles + 1` zero crossings, with its u."""

    period_s: float
    u_s: float
    amplitude_deg: float
    cycles: int
    residual_deg: float  # pooled rms residual of the crossing fits


@dataclass(frozen=True)
class RecoilEstimate:
    """Peak angular speed after the impact, its u, and where the step was found."""

    omega_rad_s: float
    u_rad_s: float
    step_time_s: float  # time of the last sample before the fitted window
    samples: int


def _arrays(t_s: Samples, angle_deg: Samples, least: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t_s, dtype=float)
    a = np.asarray(angle_deg, dtype=float)
    if t.shape != a.shape or t.ndim != 1 or len(t) < least:
        raise ParameterError("samples", len(t), f"need at least {least} (time, angle) pairs of equal length")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
        raise ParameterError("samples", "non-finite", "times and angles must be finite")
    if np.any(np.diff(t) <= 0.0):
        raise ParameterError("samples", "times", "sample times must strictly increase")
    return t, a


def _line_fit(t: np.ndarray, a: np.ndarray) -> tuple[float, float, float, float, float]:
    """(t_mean, intercept at t_mean, slope, rss, sum of squared t deviations)."""
    tm = float(t.mean())
    dt = t - tm
    sxx = float(dt @ dt)
    slope = float(dt @ (a - a.mean())) / sxx
    icpt = float(a.mean())
    res = a - (icpt + slope * dt)
    return tm, icpt, slope, float(res @ res), sxx


def _quantization_deg(resolution_deg: float, time_resolution_s: float, rate_deg_s: float) -> float:
    return math.hypot(resolution_deg, abs(rate_deg_s) * time_resolution_s) / math.sqrt(12.0)


def zero_crossings(t_s: Samples, angle_deg: Samples) -> list[int]:
    """Indices i where the angle changes sign between samples i and i+1 (across a run of zeros, about
    its middle). Zeros between the two signs are skipped: up to two always, a longer run when the
    angle moves through it at least half as fast as it moves on either side of it (a slow swing read
    by a coarse encoder dwells at zero for a few samples). A trace that rests at zero, or stops there
    and later moves off to the other side, has no crossing there."""
    _, a = _arrays(t_s, angle_deg, 2)
    out: list[int] = []
    last = -1  # index of the last non-zero sample
    for i, value in enumerate(a):
        if value == 0.0:
            continue
        if last >= 0 and (value > 0.0) != (a[last] > 0.0) and _passes_through(a, last, i):
            out.append(last + max(0, (i - last - 2) // 2))  # a long run of zeros: its middle
        last = i
    return out


def _passes_through(a: np.ndarray, last: int, i: int) -> bool:
    """Whether the zeros between the opposite-signed samples `last` and `i` are a crossing."""
    gap = i - last  # the zeros between them, plus one
    if gap <= 3:
        return True
    through = (abs(float(a[last])) + abs(float(a[i]))) / gap
    before = abs(float(a[last] - a[max(0, last - gap)])) / gap
    after = abs(float(a[min(len(a) - 1, i + gap)] - a[i])) / gap
    return through >= 0.5 * max(before, after)


def _merged(idx: list[int]) -> list[int]:
    """Crossings with noise flicker merged: sign changes much closer together than a half swing
    (a quarter of the median spacing) are noise about one crossing: an odd number of them is one
    crossing, at their middle; an even number changes no sign and is none."""
    if len(idx) < 3:
        return idx
    close = float(np.median(np.diff(idx))) / 4.0
    out: list[int] = []
    group = [idx[0]]
    for i in [*idx[1:], None]:
        if i is not None and i - group[-1] < close:
            group.append(i)
            continue
        if len(group) % 2:
            out.append(group[len(group) // 2])
        if i is not None:
            group = [i]
    return out


def swing_period(
    t_s: Samples,
    angle_deg: Samples,
    cycles: int,
    resolution_deg: float = 0.0,
    time_resolution_s: float = 0.0,
) -> PeriodEstimate:
    """The mean period of the first `cycles` full swings in the trace, and its standard uncertainty."""
    if cycles < 1:
        raise ParameterError("cycles", cycles, "need at least one cycle")
    t, a = _arrays(t_s, angle_deg, 4)
    idx = _merged(zero_crossings(t, a))
    need = 2 * cycles + 1
    if len(idx) < need:
        raise ParameterError(
            "swing", len(idx), f"{len(idx)} zero crossings in the trace, {need} needed for {cycles} cycles"
        )
    idx = idx[:need]
    # samples each side of the crossing's interval: the window stays within a third of a half swing
    half = max(1, min(4, int((idx[-1] - idx[0]) / (need - 1) / 6)))
    fits = []
    for i in idx:
        lo, hi = max(0, i - half), min(len(t), i + half + 2)
        fits.append((*_line_fit(t[lo:hi], a[lo:hi]), hi - lo))
    dof = sum(n - 2 for *_, n in fits)
    rms_resid = math.sqrt(sum(f[3] for f in fits) / dof) if dof > 0 else 0.0
    times, u_times = [], []
    for tm, icpt, slope, _rss, sxx, n in fits:
        if slope == 0.0:
            raise ParameterError("swing", "flat", "a zero crossing with no slope: the trace is not a swing")
        sigma = max(rms_resid, _quantization_deg(resolution_deg, time_resolution_s, slope))
        tc = tm - icpt / slope
        d = tc - tm
        # delta method for tc = tm - icpt/slope: var(icpt) = s^2/n, var(slope) = s^2/sxx, cov = 0
        u_tc = sigma / abs(slope) * math.sqrt(1.0 / n + d * d / sxx)
        times.append(tc)
        u_times.append(math.hypot(u_tc, time_resolution_s / math.sqrt(12.0)))
    k = np.arange(need, dtype=float)
    x = np.column_stack([np.ones(need), k, (-1.0) ** k])
    w = 1.0 / np.asarray(u_times) if min(u_times) > 0.0 else np.ones(need)
    coef, *_ = np.linalg.lstsq(x * w[:, None], np.asarray(times) * w, rcond=None)
    cov_b = np.linalg.inv((x * w[:, None]).T @ (x * w[:, None]))
    u_b = math.sqrt(cov_b[1, 1]) if min(u_times) > 0.0 else 0.0
    resid = np.asarray(times) - x @ coef
    if need > 3:  # Type A from the crossings' own scatter about the fit
        s2 = float(resid @ resid) / (need - 3)
        u_a = math.sqrt(s2 * float(np.linalg.inv(x.T @ x)[1, 1]))
        u_b = max(u_b, u_a)
    span = a[idx[0] : idx[-1] + 2]
    amplitude = float((span.max() - span.min()) / 2.0)
    return PeriodEstimate(2.0 * float(coef[1]), 2.0 * u_b, amplitude, cycles, rms_resid)


def recoil_speed(
    t_s: Samples,
    angle_deg: Samples,
    resolution_deg: float = 0.0,
    time_resolution_s: float = 0.0,
    window: int = DEFAULT_RECOIL_WINDOW,
) -> RecoilEstimate:
    """The peak angular speed (rad/s, signed as the angle moves) just after a step, and its u."""
    if window < 3:
        raise ParameterError("window", window, "fit at least 3 samples")
    t, a = _arrays(t_s, angle_deg, window + 1)
    rate = np.diff(a) / np.diff(t)
    fastest = float(np.max(np.abs(rate)))
    if fastest == 0.0:
        raise ParameterError("recoil", "flat", "the angle never moves: no recoil in the trace")
    fast = np.abs(rate) > 0.5 * fastest
    # the step: the first interval that moves fast and is followed by two more (noise rarely does that)
    steady = fast[:-2] & fast[1:-1] & fast[2:] if len(fast) > 2 else fast
    if not steady.any():
        raise ParameterError("recoil", "no step", "no steady rise of the angle: no recoil in the trace")
    j = int(np.argmax(steady))
    start = j + 1  # sample j may precede the step; j + 1 lies after it
    if start + window > len(t):
        raise ParameterError(
            "recoil", len(t) - start, f"{len(t) - start} samples after the step, {window} needed"
        )
    tw, aw = t[start : start + window], a[start : start + window]
    _tm, _icpt, slope, rss, sxx = _line_fit(tw, aw)
    # the noise: the fit's residual pooled with the scatter of the flat trace before the step
    base = a[:j]
    rss_base = float(((base - base.mean()) ** 2).sum()) if len(base) > 1 else 0.0
    pooled = math.sqrt((rss + rss_base) / (window - 2 + max(0, len(base) - 1)))
    sigma = max(pooled, _quantization_deg(resolution_deg, time_resolution_s, slope))
    per_sample = abs(slope) * float(np.median(np.diff(tw)))
    if per_sample < RESOLVED_STEPS * sigma:
        raise ParameterError(
            "recoil",
            f"{per_sample:.3g} deg per sample",
            f"not resolved: the angle moves less than {RESOLVED_STEPS:g} times its noise "
            f"({sigma:.3g} deg) per sample; raise the sample rate's resolution or lower its noise",
        )
    u = sigma / math.sqrt(sxx)
    return RecoilEstimate(math.radians(slope), math.radians(u), float(t[j]), window)
