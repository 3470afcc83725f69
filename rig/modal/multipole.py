"""Close modes: several poles fitted together, and a search for a pole the peak finder missed.

Peaks whose fit bands overlap are fitted together (polefit.py: the model of modes.py with P poles
sharing the two FRFs over one band). Where a fit's residual over a wider band exceeds the noise,
hidden.py searches it for a hidden pole; a pole found is refitted over its own band, and how far
its frequency moves between the two bands is a model-error term. Each hit's FRFs are fitted
again from the final poles for the spread of the hits.

The work goes in stages over every group at once (the joint fits, the wide fits, the search, the
narrowed fits, the per-hit fits), so that each stage's fits are solved together in one batch
(polefit.fit_many); each fit's result is the one it would have alone.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from rig.modal.frf import FrfEstimate
from rig.modal.hidden import MAX_POLES, Band, Setting, extra_poles
from rig.modal.modes import MIN_FIT_BINS, Peak, PoleFit, fit_band, fit_mode
from rig.modal.polefit import MultiFit, Problem, fit_many, fit_poles

__all__ = ["MAX_POLES", "ModeFit", "MultiFit", "fit_modes", "fit_poles", "group_peaks"]

GROUP_BANDWIDTHS = 5.0  # peaks closer than this many half-power bandwidths are fitted together
WIDE_BANDWIDTHS = 4.0  # the band searched for a hidden pole: +- this many bandwidths
NOISE_GATE = 1.5  # residual power over the noise's expected power above which a hidden pole is sought


@dataclass(frozen=True)
class ModeFit:
    """One mode as fitted: the fit, the peak it came from (made up for a hidden pole), per-hit values."""

    fit: PoleFit
    peak: Peak
    per_hit_hz: tuple[float, ...]
    hidden: bool  # found by the model-order test, not by the peak finder
    u_model_hz: float = 0.0  # model-error term (close modes), see _narrowed and _unresolved
    note: str = ""  # a warning for the result
    unresolved: bool = False  # a second pole within 1/T was seen: the residues (and kind) are a blend


def group_peaks(peaks: list[Peak]) -> list[list[int]]:
    """Indices of consecutive peaks whose fit bands overlap (within GROUP_BANDWIDTHS bandwidths)."""
    groups: list[list[int]] = []
    for i, p in enumerate(peaks):
        if groups and len(groups[-1]) < MAX_POLES:
            q = peaks[groups[-1][-1]]
            if p.frequency_hz - q.frequency_hz < GROUP_BANDWIDTHS * 0.5 * (p.bandwidth_hz + q.bandwidth_hz):
                groups[-1].append(i)
                continue
        groups.append([i])
    return groups


def _span(frf: FrfEstimate, peaks: list[Peak], members: list[int], widths: float) -> tuple[int, int]:
    """Bins covering +- `widths` bandwidths around the members, at most halfway to the other peaks."""
    first, last = peaks[members[0]], peaks[members[-1]]
    lo = min(
        p.index - max(widths * p.bandwidth_hz, 4.0 * frf.df) / frf.df for p in (peaks[i] for i in members)
    )
    hi = max(
        p.index + max(widths * p.bandwidth_hz, 4.0 * frf.df) / frf.df for p in (peaks[i] for i in members)
    )
    if members[0] > 0:
        lo = max(lo, 0.5 * (peaks[members[0] - 1].index + first.index))
    if members[-1] + 1 < len(peaks):
        hi = min(hi, 0.5 * (peaks[members[-1] + 1].index + last.index))
    lo_i = max(1, math.floor(lo))
    hi_i = min(frf.freq_hz.size, math.ceil(hi) + 1)
    while hi_i - lo_i < MIN_FIT_BINS and (lo_i > 1 or hi_i < frf.freq_hz.size):
        lo_i, hi_i = max(1, lo_i - 1), min(frf.freq_hz.size, hi_i + 1)
    return lo_i, hi_i


def _fit_all(
    frf: FrfEstimate, jobs: Sequence[tuple[Sequence[complex], tuple[int, int]]], h: np.ndarray | None = None
) -> list[MultiFit | None]:
    """Fits of (guesses, bins) to the averaged FRFs (or to h), solved together."""
    data = frf.h if h is None else h
    problems = [Problem(data[:, lo:hi], frf.s[lo:hi], tuple(g), (lo, hi)) for g, (lo, hi) in jobs]
    return fit_many(problems, frf.dt, frf.enbw_bins)


def _guess(p: Peak) -> complex:
    wn = 2 * math.pi * p.frequency_hz
    return complex(-max(p.damping_hp, 1e-4) * wn, wn)


def _per_hit(frf: FrfEstimate, fits: list[MultiFit]) -> list[list[list[float]]]:
    """Per fit and pole, the frequencies of the same joint fit to each hit's FRFs (all at once)."""
    out: list[list[list[float]]] = [[[] for _ in fit.poles] for fit in fits]
    if frf.n_hits < 2 or not fits:
        return out
    problems = [
        Problem(
            frf.per_hit[k][:, fit.bins[0] : fit.bins[1]],
            frf.s[fit.bins[0] : fit.bins[1]],
            fit.poles,
            fit.bins,
        )
        for fit in fits
        for k in range(frf.n_hits)
    ]
    ones = fit_many(problems, frf.dt, frf.enbw_bins)
    for j, one in enumerate(ones):
        if one is not None:
            for i, f in enumerate(one.frequencies_hz):
                out[j // frf.n_hits][i].append(f)
    return out


def _made_up_peak(frf: FrfEstimate, f_hz: float, zeta: float) -> Peak:
    k = int(np.argmin(np.abs(frf.freq_hz - f_hz)))
    bw = 2 * zeta * f_hz + 1.0 / (math.pi * frf.tau_s)
    return Peak(k, f_hz, bw, zeta)


@dataclass
class _Group:
    """One group of peaks through the stages, and how its modes come out."""

    members: list[int]
    guesses: list[complex]
    joint: MultiFit | None = None
    moved: tuple[float, ...] | None = None  # model-error terms
    final: MultiFit | None = None  # the fit whose poles are the modes
    hint: MultiFit | None = None  # an unseparable extra pole seen beside the joint fit's


def fit_modes(frf: FrfEstimate, peaks: list[Peak], check_order: bool = True) -> list[ModeFit]:
    """Every peak's mode, close peaks fitted together; a pole hidden in a peak added if the data demand it."""
    groups = [_Group(m, [_guess(peaks[i]) for i in m]) for m in group_peaks(peaks)]
    bands = [
        fit_band(frf, peaks, g.members[0]) if len(g.members) == 1 else _span(frf, peaks, g.members, 2.5)
        for g in groups
    ]
    for g, joint in zip(
        groups, _fit_all(frf, [(g.guesses, b) for g, b in zip(groups, bands, strict=True)]), strict=True
    ):
        g.joint = g.final = joint
    if check_order:
        _search(frf, peaks, [g for g in groups if len(g.members) < MAX_POLES])
    fitted = [g for g in groups if g.final is not None]
    per_hit = _per_hit(frf, [g.final for g in fitted if g.final is not None])
    hits_of = {id(g): hits for g, hits in zip(fitted, per_hit, strict=True)}
    out: list[ModeFit] = []
    for g in groups:
        if g.final is None:
            out += _alone(frf, peaks, g.members)
            continue
        fits = _modes_of(frf, peaks, g.members, g.final, hits_of[id(g)], g.moved)
        if g.hint is not None:
            fits = _unresolved(frf, g.final, g.hint, fits)
        out += fits
    return out


def _search(frf: FrfEstimate, peaks: list[Peak], groups: list[_Group]) -> None:
    """Wide fits, the search for hidden poles where their residual exceeds the noise, and the
    narrowed refits of the poles found: each group's final fit, model-error terms and hint."""
    jobs = [
        (list(g.joint.poles) if g.joint else g.guesses, _span(frf, peaks, g.members, WIDE_BANDWIDTHS))
        for g in groups
    ]
    searched = [
        (g, w)
        for g, w in zip(groups, _fit_all(frf, jobs), strict=True)
        if w is not None and _structured(frf, w)
    ]
    for g, wide in searched:
        if g.joint is not None:  # the residual shows what the model leaves: how far does f move?
            g.moved = tuple(
                abs(a - b) for a, b in zip(g.joint.frequencies_hz, wide.frequencies_hz, strict=True)
            )
    bands = [Band(frf.h[:, w.bins[0] : w.bins[1]], frf.s[w.bins[0] : w.bins[1]], w) for _, w in searched]
    found = extra_poles(bands, Setting(frf.dt, frf.tau_s, frf.enbw_bins, frf.df))
    more = [(g, m) for (g, _), (m, _) in zip(searched, found, strict=True) if m is not None]
    for (g, _), (m, hint) in zip(searched, found, strict=True):
        if m is None and g.joint is not None:
            g.hint = hint
    for (g, _), (fit, moved) in zip(more, _narrowed(frf, [m for _, m in more]), strict=True):
        g.final, g.moved, g.hint = fit, moved, None


def _alone(frf: FrfEstimate, peaks: list[Peak], members: list[int]) -> list[ModeFit]:
    """Where the joint fit failed: each peak's own single-mode fit (half-power if that fails too)."""
    out = []
    for i in members:
        fit = fit_mode(frf, peaks[i], fit_band(frf, peaks, i))
        hits = (
            [fit_mode(frf, peaks[i], fit.bins, frf.per_hit[k]) for k in range(frf.n_hits)]
            if frf.n_hits >= 2
            else []
        )
        per_hit = tuple(f.frequency_hz for f in hits if f.method == "pole fit")
        out.append(ModeFit(fit, peaks[i], per_hit, False))
    return out


def _structured(frf: FrfEstimate, fit: MultiFit) -> bool:
    """False if the fit's residual is no larger than the FRF's noise explains (the search for a
    hidden pole is then skipped: it costs most of the analysis); True if it is, or if the noise is
    unknown."""
    if frf.noise_h is None:
        return True
    lo, hi = fit.bins
    expected = float(np.sum(frf.noise_h[:, lo:hi] ** 2))
    return not expected > 0 or float(np.sum(np.abs(fit.residual) ** 2)) > NOISE_GATE * expected


def _narrowed(frf: FrfEstimate, wides: list[MultiFit]) -> list[tuple[MultiFit, tuple[float, ...]]]:
    """The poles found over each wide band, refitted over +-2.5 of their bandwidths (inside it), and
    per pole how far the frequency moved: the straight line stands in for the far modes less well
    over a wider band, so the move measures what the model leaves (a model-error term)."""
    bins = [_narrow_bins(frf, w) for w in wides]
    refit = [i for i, (w, b) in enumerate(zip(wides, bins, strict=True)) if b != w.bins]
    narrows = dict(zip(refit, _fit_all(frf, [(wides[i].poles, bins[i]) for i in refit]), strict=True))
    out = []
    for i, wide in enumerate(wides):
        narrow = narrows.get(i)
        if narrow is None or len(narrow.poles) != len(wide.poles):
            out.append((wide, tuple(0.0 for _ in wide.poles)))
            continue
        moved = tuple(abs(a - b) for a, b in zip(narrow.frequencies_hz, wide.frequencies_hz, strict=True))
        out.append((narrow, moved))
    return out


def _narrow_bins(frf: FrfEstimate, wide: MultiFit) -> tuple[int, int]:
    """+-2.5 bandwidths (at least 4 bins) around the wide fit's poles, inside its band."""
    bw = [
        2 * z * f + 1.0 / (math.pi * frf.tau_s)
        for f, z in zip(wide.frequencies_hz, wide.damping_ratios, strict=True)
    ]
    f_lo = min(f - max(2.5 * b, 4.0 * frf.df) for f, b in zip(wide.frequencies_hz, bw, strict=True))
    f_hi = max(f + max(2.5 * b, 4.0 * frf.df) for f, b in zip(wide.frequencies_hz, bw, strict=True))
    return max(wide.bins[0], math.floor(f_lo / frf.df)), min(wide.bins[1], math.ceil(f_hi / frf.df) + 1)


def _unresolved(frf: FrfEstimate, joint: MultiFit, hint: MultiFit, fits: list[ModeFit]) -> list[ModeFit]:
    """The joint fit's modes where its residual shows another pole that cannot be separated: each
    frequency gets as a model-error term how far the extra pole moves it, and a warning names the
    frequencies."""
    moved = tuple(min(abs(f - g) for g in hint.frequencies_hz) for f in joint.frequencies_hz)
    extra = [g for g in hint.frequencies_hz if min(abs(g - f) for f in joint.frequencies_hz) > 0.5 * frf.df]
    shown = ", ".join(f"{f:.1f}" for f in sorted([*joint.frequencies_hz, *extra]))
    note = (
        f"the peak at {joint.frequencies_hz[0]:.1f} Hz looks like close modes ({shown} Hz"
        f"{'' if extra else ' and one within 1/T of it'}) that this record cannot separate"
        f" (resolution 1/T = {frf.df:.3g} Hz): its uncertainty includes the difference;"
        f" record longer per hit to separate them"
    )
    return [
        replace(m, u_model_hz=moved[i], note=note if i == 0 else "", unresolved=True)
        for i, m in enumerate(fits)
    ]


def _modes_of(
    frf: FrfEstimate,
    peaks: list[Peak],
    members: list[int],
    fit: MultiFit,
    per_hit: list[list[float]],
    u_model: tuple[float, ...] | None = None,
) -> list[ModeFit]:
    """One ModeFit per pole; each found peak goes with its nearest pole, the others are hidden poles."""
    freqs = fit.frequencies_hz
    owner: dict[int, int] = {}
    for i in members:
        j = int(
            np.argmin(
                [abs(f - peaks[i].frequency_hz) if r not in owner else math.inf for r, f in enumerate(freqs)]
            )
        )
        owner[j] = i
    out = []
    close = [(a, b) for a, b in itertools.pairwise(freqs) if b - a < 2.0 * frf.df]
    note = "; ".join(
        f"modes at {a:.1f} and {b:.1f} Hz are closer than 2/T = {2 * frf.df:.3g} Hz: too close to"
        f" separate reliably at this record length; record longer per hit"
        for a, b in close
    )
    for r, (f, z) in enumerate(zip(freqs, fit.damping_ratios, strict=True)):
        pole_fit = PoleFit(f, z, fit.residues[r], fit.u_frequency_hz[r], fit.bins, "pole fit")
        peak = peaks[owner[r]] if r in owner else _made_up_peak(frf, f, z)
        u_m = 0.0 if u_model is None else u_model[r]
        out.append(ModeFit(pole_fit, peak, tuple(per_hit[r]), r not in owner, u_m, note if r == 0 else ""))
    return out
