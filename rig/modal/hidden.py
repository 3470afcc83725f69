"""A test for a pole the peak finder missed, for many bands at once.

A pole hidden in a neighbour's peak (the two merge in the mode indicator, so the peak finder sees
one) shows as structure in the fit's residual. `extra_poles` adds a pole where the residual is
largest and keeps it only if it explains much more than noise would (an F test between the two
model orders, its degrees of freedom divided by the ENBW since neighbouring bins are correlated),
lies inside the band, apart from the others (their k = 2 intervals do not overlap), is mode-like
(damping not far above the others') and carries a visible share of the FRF.

Poles are added while the data demand them, up to MAX_POLES: one at a time at the residual's
largest local maximum, or, where one alone is not demanded, two at its two largest (two hidden
modes on either side of a peak leave each other in the residual, so that the F test of either
alone fails: a real recording showed it). Every band takes its steps at the same time, and the
trial fits of one step are solved together (polefit.fit_many).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import fdtri

from rig.modal.polefit import MultiFit, Problem, fit_many, peak_height

F_TEST_P = 1e-6  # an extra pole is kept only if this unlikely under the smaller model
MIN_SHARE = 0.05  # ... and its peak reaches this fraction of the band's largest |H|
MAX_DAMPING = 0.1  # ... and it is a mode, not a broad term standing in for the far modes:
BANDWIDTH_SHARE = 0.25  # an extra pole must lie this share of the wider half-power bandwidth apart
DAMPING_FACTOR = 5.0  # damping at most this times the largest of the other poles' and MAX_DAMPING
MAX_POLES = 4


@dataclass(frozen=True)
class Band:
    """The FRFs h (2, K) at s (K,) of a band and the fit whose residual is searched."""

    h: np.ndarray
    s: np.ndarray
    fit: MultiFit


@dataclass(frozen=True)
class Setting:
    """What the tests need beside the data: the sampling, the window, the noise's correlation."""

    dt: float
    tau: float
    enbw: float
    min_separation_hz: float


def extra_poles(bands: list[Band], setting: Setting) -> list[tuple[MultiFit | None, MultiFit | None]]:
    """Per band: its fit with more poles if the data demand them (module docstring), else None; and
    the trial with one more pole where the residual shows a mode-like pole closer than
    `min_separation_hz` to another (it cannot be separated), else None."""
    base = [b.fit for b in bands]
    kept: list[MultiFit | None] = [None] * len(bands)
    result: list[tuple[MultiFit | None, MultiFit | None]] = [(None, None)] * len(bands)
    active = list(range(len(bands)))
    while active:
        more, hints = _step([bands[i] for i in active], [base[i] for i in active], setting)
        still = []
        for i, m, hint in zip(active, more, hints, strict=True):
            if m is None:
                result[i] = (kept[i], hint if kept[i] is None else None)
            else:
                kept[i] = base[i] = m
                still.append(i)
        active = still
    return result


def _step(
    bands: list[Band], bases: list[MultiFit], setting: Setting
) -> tuple[list[MultiFit | None], list[MultiFit | None]]:
    """One step for every band: its base with one (else two) more poles if demanded, and a hint."""
    more: list[MultiFit | None] = [None] * len(bands)
    hints: list[MultiFit | None] = [None] * len(bands)
    starts = [_starts(b.s, base) for b, base in zip(bands, bases, strict=True)]
    pending = list(range(len(bands)))
    for n_extra in (1, 2):
        tried = [
            i for i in pending if len(starts[i]) >= n_extra and len(bases[i].poles) + n_extra <= MAX_POLES
        ]
        problems = [
            Problem(bands[i].h, bands[i].s, (*bases[i].poles, *starts[i][:n_extra]), bases[i].bins)
            for i in tried
        ]
        pending = []
        for i, trial in zip(tried, fit_many(problems, setting.dt, setting.enbw), strict=True):
            verdict = None if trial is None else _judge(trial, bases[i], bands[i], setting)
            if verdict == "keep":
                more[i] = trial
                continue
            if verdict == "close" and hints[i] is None:
                hints[i] = trial
            pending.append(i)
    return more, hints


def _starts(s: np.ndarray, base: MultiFit) -> list[complex]:
    """Starting poles at the residual's local maxima, largest first (none if the band is too narrow)."""
    k = s.size
    edge = max(2, k // 10)
    if k <= 2 * edge + 1:
        return []
    power = np.sum(np.abs(base.residual) ** 2, axis=0)
    smooth = np.convolve(power, np.ones(3) / 3.0, mode="same")
    inner = smooth[edge : k - edge]
    maxima = [
        i
        for i in range(inner.size)
        if inner[i] >= inner[max(i - 1, 0)] and inner[i] >= inner[min(i + 1, inner.size - 1)]
    ]
    maxima.sort(key=lambda i: -inner[i])
    sigma0 = float(np.median([-p.real for p in base.poles]))
    return [complex(-sigma0, s.imag[edge + i]) for i in maxima[:2]]


def _judge(trial: MultiFit, base: MultiFit, band: Band, setting: Setting) -> str | None:
    """'keep' if the extra poles pass every test, 'close' if one is mode-like but too close to
    another to separate, else None."""
    if not trial.cost < base.cost:
        return None
    enbw = setting.enbw
    dof2 = (trial.n_residuals - trial.n_params) / enbw
    f_stat = ((base.cost - trial.cost) / (trial.n_params - base.n_params)) / (
        trial.cost / (trial.n_residuals - trial.n_params)
    )
    f_stat /= enbw  # correlated bins: the extra columns take up about enbw times the noise if white
    # the F distribution's upper F_TEST_P point (what scipy.stats.f.isf computes, without importing it)
    if f_stat < fdtri(trial.n_params - base.n_params, max(dof2, 1.0), 1.0 - F_TEST_P):
        return None
    if max(trial.damping_ratios) > min(MAX_DAMPING, DAMPING_FACTOR * max(base.damping_ratios)):
        return None
    freqs = trial.frequencies_hz
    # apart by the resolution, and by a share of the pair's half-power bandwidth: poles closer than
    # that are one broad peak to the data (a noisy 4 s record made a 'hoop' 0.9 Hz from a bending
    # mode 5.5 Hz wide)
    widths = [2.0 * z * f for f, z in zip(freqs, trial.damping_ratios, strict=True)]
    apart = [
        max(setting.min_separation_hz, BANDWIDTH_SHARE * max(widths[i], widths[i + 1]))
        for i in range(len(freqs) - 1)
    ]
    if any(b - a < gap for a, b, gap in zip(freqs, freqs[1:], apart, strict=False)):
        return "close" if len(trial.poles) == len(base.poles) + 1 else None
    u = trial.u_frequency_hz
    if any(2.0 * (u[i] + u[i + 1]) >= freqs[i + 1] - freqs[i] for i in range(len(freqs) - 1)):
        return None  # the poles' intervals (k = 2) overlap: a pole the data do not pin down
    omega = band.s.imag
    span = (omega.min() / (2 * math.pi), omega.max() / (2 * math.pi))
    margin = 0.05 * (span[1] - span[0])
    if not all(span[0] + margin < f < span[1] - margin for f in freqs):
        return None
    top = float(np.max(np.abs(band.h)))
    if min(peak_height(trial, i, setting.dt, setting.tau) for i in range(len(freqs))) < MIN_SHARE * top:
        return None
    return "keep"
