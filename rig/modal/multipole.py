"""Close modes: several poles fitted together, and a test for a pole the peak finder missed.

The model of modes.py with P poles sharing the two FRFs over one band:
    H_i(k) = sum_r [R_ir / (1 - exp((p_r - s_k) dt)) + conj(R_ir) / (1 - exp((conj(p_r) - s_k) dt))]
             + C_i + D_i x_k
Residues and lines are linear (solved for every trial set of poles, variable projection); the
poles by scipy.optimize.least_squares. The Jacobian gives each frequency's standard uncertainty,
scaled by sqrt(ENBW in bins) as in modes.py.

A pole hidden in a neighbour's peak (the two merge in the mode indicator, so the peak finder sees
one) shows as structure in the fit's residual. `extra_pole` adds a pole where the residual is
largest and keeps it only if it explains much more than noise would (an F test between the two
model orders, its degrees of freedom divided by the ENBW since neighbouring bins are correlated),
lies inside the band, apart from the others (their k = 2 intervals do not overlap), is mode-like
(damping not far above the others') and carries a visible share of the FRF.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import f as f_dist

from rig.modal.frf import FrfEstimate
from rig.modal.modes import MIN_FIT_BINS, Peak, PoleFit, fit_band, fit_mode

N_LINE = 4  # per FRF: C and D, complex
F_TEST_P = 1e-6  # an extra pole is kept only if this unlikely under the smaller model
MIN_SHARE = 0.05  # ... and its peak reaches this fraction of the band's largest |H|
MAX_DAMPING = 0.1  # ... and it is a mode, not a broad term standing in for the far modes:
BANDWIDTH_SHARE = 0.25  # an extra pole must lie this share of the wider half-power bandwidth apart
DAMPING_FACTOR = 5.0  # damping at most this times the largest of the other poles' and MAX_DAMPING


@dataclass(frozen=True)
class MultiFit:
    """Poles fitted together over one band of bins."""

    poles: tuple[complex, ...]  # ascending frequency
    residues: tuple[tuple[complex, complex], ...]  # per pole: at accelerometer 1 and 2
    u_frequency_hz: tuple[float, ...]  # per pole, standard uncertainty from the Jacobian
    cost: float  # half the sum of squared (scaled) residuals
    n_residuals: int
    bins: tuple[int, int]
    residual: np.ndarray  # (2, K) complex, in the FRFs' units

    @property
    def frequencies_hz(self) -> tuple[float, ...]:
        """Natural frequencies |p| / 2 pi."""
        return tuple(abs(p) / (2 * math.pi) for p in self.poles)

    @property
    def damping_ratios(self) -> tuple[float, ...]:
        """sigma / |p| per pole."""
        return tuple(-p.real / abs(p) for p in self.poles)

    @property
    def n_params(self) -> int:
        """Fitted real parameters: 2 per pole, and per FRF 2 per residue and the line."""
        n = len(self.poles)
        return 2 * n + 2 * (2 * n + N_LINE)


def _basis(poles: np.ndarray, s: np.ndarray, dt: float, x: np.ndarray) -> np.ndarray:
    cols = []
    for p in poles:
        g1 = 1.0 / -np.expm1((p - s) * dt)
        g2 = 1.0 / -np.expm1((np.conj(p) - s) * dt)
        cols += [g1 + g2, 1j * (g1 - g2)]
    one = np.ones_like(x)
    cols += [one, 1j * one, x, 1j * x]
    a = np.stack(cols, axis=1)
    return np.vstack([a.real, a.imag])


def _linear(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares coefficients: normal equations on unit-norm columns (small and fast; an
    SVD per trial pole cost most of the analysis), the SVD where they are singular."""
    norms = np.linalg.norm(a, axis=0)
    norms[norms == 0] = 1.0
    an = a / norms
    try:
        c = np.linalg.solve(an.T @ an, an.T @ y)
    except np.linalg.LinAlgError:
        c = np.full((a.shape[1], y.shape[1]), np.nan)
    if not np.all(np.isfinite(c)):
        c, *_ = np.linalg.lstsq(an, y, rcond=None)
    return c / norms[:, None]


def fit_poles(
    h: np.ndarray, s: np.ndarray, dt: float, guesses: list[complex], enbw: float, bins: tuple[int, int]
) -> MultiFit | None:
    """Fit len(guesses) poles jointly to the FRFs h (2, K) at s (K,); None if the fit fails."""
    n = len(guesses)
    w0 = float(np.mean([abs(g) for g in guesses]))
    omega = s.imag
    x = (omega - omega.mean()) / w0
    scale = np.array([float(np.max(np.abs(hi))) or 1.0 for hi in h])
    y = np.stack([np.concatenate([hi.real, hi.imag]) for hi in h], axis=1) / scale  # (2K, 2)
    m = y.size
    if m <= 2 * n + 2 * (2 * n + N_LINE):
        return None

    def poles_of(theta: np.ndarray) -> np.ndarray:
        return (-theta[0::2] + 1j * theta[1::2]) * w0

    def solve(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        a = _basis(poles_of(theta), s, dt, x)
        c = _linear(a, y)
        r = a @ c - y
        return r.T.ravel(), c, a

    lo, hi = omega.min() / w0, omega.max() / w0
    theta0 = np.empty(2 * n)
    for i, g in enumerate(guesses):
        theta0[2 * i] = min(max(-g.real / w0, 1e-6), 0.49)
        theta0[2 * i + 1] = min(max(g.imag / w0, lo + 1e-9), hi - 1e-9)
    bounds = ([0.0, lo] * n, [0.5, hi] * n)

    def residuals(theta: np.ndarray) -> np.ndarray:
        return solve(theta)[0]

    try:
        out = least_squares(residuals, theta0, bounds=bounds, x_scale=1e-3)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not out.success or not np.all(np.isfinite(out.x)):
        return None
    poles = poles_of(out.x)
    if not np.all((lo * w0 < poles.imag) & (poles.imag < hi * w0)):
        return None
    _, coefs, a = solve(out.x)
    coefs = coefs * scale
    r = a @ coefs - y * scale
    k = s.size
    residual = np.stack([r[:k, i] + 1j * r[k:, i] for i in range(2)])
    n_par = 2 * n + 2 * (2 * n + N_LINE)
    s2 = 2.0 * out.cost / (m - n_par)
    try:
        jac = np.asarray(out.jac)  # dense: no jac_sparsity, the default trust-region solver
        cov = s2 * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cov = np.full((2 * n, 2 * n), np.nan)
    u = []
    for i, p in enumerate(poles):
        grad = np.array([-p.real, p.imag]) / abs(p) * w0
        block = cov[2 * i : 2 * i + 2, 2 * i : 2 * i + 2]
        var = float(grad @ block @ grad)
        u.append(
            math.sqrt(var * max(enbw, 1.0)) / (2 * math.pi) if math.isfinite(var) and var >= 0 else math.inf
        )
    order = np.argsort(np.abs(poles))
    res = [
        (complex(coefs[2 * i, 0], coefs[2 * i + 1, 0]), complex(coefs[2 * i, 1], coefs[2 * i + 1, 1]))
        for i in order
    ]
    return MultiFit(
        tuple(complex(poles[i]) for i in order),
        tuple(res),
        tuple(u[i] for i in order),
        float(out.cost),
        m,
        bins,
        residual,
    )


def peak_height(fit: MultiFit, i: int, dt: float, tau: float) -> float:
    """|H| that pole i alone gives at its own frequency on the more responsive accelerometer."""
    p = fit.poles[i]
    s = 1j * p.imag + 1.0 / tau
    g = 1.0 / -np.expm1((p - s) * dt)
    return max(abs(r) * abs(g) for r in fit.residues[i])


def extra_pole(
    h: np.ndarray,
    s: np.ndarray,
    dt: float,
    tau: float,
    base: MultiFit,
    enbw: float,
    min_separation_hz: float,
) -> tuple[MultiFit | None, MultiFit | None]:
    """`base` with more poles if the data demand them (see the module's docstring), else None; and
    the trial with one more pole where the residual shows a mode-like pole closer than
    `min_separation_hz` to another (it cannot be separated), else None.

    Poles are added while the data demand them, up to MAX_POLES: one at a time at the residual's
    largest local maximum, or, where one alone is not demanded, two at its two largest (two hidden
    modes on either side of a peak leave each other in the residual, so that the F test of either
    alone fails: a real recording showed it).
    """
    kept: MultiFit | None = None
    while True:
        more, close = _add_poles(h, s, dt, tau, kept or base, enbw, min_separation_hz)
        if more is None:
            return kept, (close if kept is None else None)
        kept = more


def _add_poles(
    h: np.ndarray,
    s: np.ndarray,
    dt: float,
    tau: float,
    base: MultiFit,
    enbw: float,
    min_separation_hz: float,
) -> tuple[MultiFit | None, MultiFit | None]:
    """One step of `extra_pole`: `base` with one (else two) more poles if demanded, and a hint."""
    k = s.size
    edge = max(2, k // 10)
    if k <= 2 * edge + 1:
        return None, None
    power = np.sum(np.abs(base.residual) ** 2, axis=0)
    smooth = np.convolve(power, np.ones(3) / 3.0, mode="same")
    inner = smooth[edge : k - edge]
    maxima = [
        i
        for i in range(inner.size)
        if inner[i] >= inner[max(i - 1, 0)] and inner[i] >= inner[min(i + 1, inner.size - 1)]
    ]
    maxima.sort(key=lambda i: -inner[i])
    omega = s.imag
    sigma0 = float(np.median([-p.real for p in base.poles]))
    hint = None
    for n_extra in (1, 2):
        if len(maxima) < n_extra or len(base.poles) + n_extra > MAX_POLES:
            break
        guesses = [complex(-sigma0, omega[edge + i]) for i in maxima[:n_extra]]
        trial = fit_poles(h, s, dt, [*base.poles, *guesses], enbw, base.bins)
        verdict = None if trial is None else _judge(trial, base, h, s, dt, tau, enbw, min_separation_hz)
        if verdict == "keep":
            return trial, None
        if verdict == "close" and hint is None:
            hint = trial
    return None, hint


def _judge(
    trial: MultiFit,
    base: MultiFit,
    h: np.ndarray,
    s: np.ndarray,
    dt: float,
    tau: float,
    enbw: float,
    min_separation_hz: float,
) -> str | None:
    """'keep' if the extra poles pass every test, 'close' if one is mode-like but too close to
    another to separate, else None."""
    if not trial.cost < base.cost:
        return None
    dof2 = (trial.n_residuals - trial.n_params) / enbw
    f_stat = ((base.cost - trial.cost) / (trial.n_params - base.n_params)) / (
        trial.cost / (trial.n_residuals - trial.n_params)
    )
    f_stat /= enbw  # correlated bins: the extra columns take up about enbw times the noise if white
    if f_stat < f_dist.isf(F_TEST_P, trial.n_params - base.n_params, max(dof2, 1.0)):
        return None
    if max(trial.damping_ratios) > min(MAX_DAMPING, DAMPING_FACTOR * max(base.damping_ratios)):
        return None
    freqs = trial.frequencies_hz
    # apart by the resolution, and by a share of the pair's half-power bandwidth: poles closer than
    # that are one broad peak to the data (a noisy 4 s record made a 'hoop' 0.9 Hz from a bending
    # mode 5.5 Hz wide)
    widths = [2.0 * z * f for f, z in zip(freqs, trial.damping_ratios, strict=True)]
    apart = [
        max(min_separation_hz, BANDWIDTH_SHARE * max(widths[i], widths[i + 1])) for i in range(len(freqs) - 1)
    ]
    if any(b - a < gap for a, b, gap in zip(freqs, freqs[1:], apart, strict=False)):
        return "close" if len(trial.poles) == len(base.poles) + 1 else None
    u = trial.u_frequency_hz
    if any(2.0 * (u[i] + u[i + 1]) >= freqs[i + 1] - freqs[i] for i in range(len(freqs) - 1)):
        return None  # the poles' intervals (k = 2) overlap: a pole the data do not pin down
    omega = s.imag
    span = (omega.min() / (2 * math.pi), omega.max() / (2 * math.pi))
    margin = 0.05 * (span[1] - span[0])
    if not all(span[0] + margin < f < span[1] - margin for f in freqs):
        return None
    top = float(np.max(np.abs(h)))
    if min(peak_height(trial, i, dt, tau) for i in range(len(freqs))) < MIN_SHARE * top:
        return None
    return "keep"


GROUP_BANDWIDTHS = 5.0  # peaks closer than this many half-power bandwidths are fitted together
WIDE_BANDWIDTHS = 4.0  # the band searched for a hidden pole: +- this many bandwidths
MAX_POLES = 4
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


def _fit(
    frf: FrfEstimate, guesses: list[complex], bins: tuple[int, int], h: np.ndarray | None = None
) -> MultiFit | None:
    lo, hi = bins
    data = (frf.h if h is None else h)[:, lo:hi]
    return fit_poles(data, frf.s[lo:hi], frf.dt, guesses, frf.enbw_bins, bins)


def _guess(p: Peak) -> complex:
    wn = 2 * math.pi * p.frequency_hz
    return complex(-max(p.damping_hp, 1e-4) * wn, wn)


def _per_hit(frf: FrfEstimate, fit: MultiFit) -> list[list[float]]:
    """Per pole, the frequencies of the same joint fit to each hit's FRFs."""
    out: list[list[float]] = [[] for _ in fit.poles]
    if frf.n_hits < 2:
        return out
    for k in range(frf.n_hits):
        one = _fit(frf, list(fit.poles), fit.bins, frf.per_hit[k])
        if one is not None:
            for i, f in enumerate(one.frequencies_hz):
                out[i].append(f)
    return out


def _made_up_peak(frf: FrfEstimate, f_hz: float, zeta: float) -> Peak:
    k = int(np.argmin(np.abs(frf.freq_hz - f_hz)))
    bw = 2 * zeta * f_hz + 1.0 / (math.pi * frf.tau_s)
    return Peak(k, f_hz, bw, zeta)


def fit_modes(frf: FrfEstimate, peaks: list[Peak], check_order: bool = True) -> list[ModeFit]:
    """Every peak's mode, close peaks fitted together; a pole hidden in a peak added if the data demand it."""
    out: list[ModeFit] = []
    for members in group_peaks(peaks):
        guesses = [_guess(peaks[i]) for i in members]
        bins = fit_band(frf, peaks, members[0]) if len(members) == 1 else _span(frf, peaks, members, 2.5)
        joint = _fit(frf, guesses, bins)
        hint, moved = None, None
        if check_order and len(members) < MAX_POLES:
            wide_bins = _span(frf, peaks, members, WIDE_BANDWIDTHS)
            wide = _fit(frf, list(joint.poles) if joint else guesses, wide_bins)
            if wide is not None and _structured(frf, wide):
                if joint is not None:  # the residual shows what the model leaves: how far does f move?
                    moved = tuple(
                        abs(a - b) for a, b in zip(joint.frequencies_hz, wide.frequencies_hz, strict=True)
                    )
                lo, hi = wide_bins
                more, hint = extra_pole(
                    frf.h[:, lo:hi], frf.s[lo:hi], frf.dt, frf.tau_s, wide, frf.enbw_bins, frf.df
                )
                if more is not None:
                    out += _modes_of(frf, peaks, members, *_narrowed(frf, more))
                    continue
        if joint is not None and hint is not None:
            out += _unresolved(frf, peaks, members, joint, hint)
            continue
        if joint is None:
            for i in members:
                fit = fit_mode(frf, peaks[i], fit_band(frf, peaks, i))
                hits = (
                    [fit_mode(frf, peaks[i], fit.bins, frf.per_hit[k]) for k in range(frf.n_hits)]
                    if frf.n_hits >= 2
                    else []
                )
                per_hit = tuple(f.frequency_hz for f in hits if f.method == "pole fit")
                out.append(ModeFit(fit, peaks[i], per_hit, False))
            continue
        out += _modes_of(frf, peaks, members, joint, moved)
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


def _narrowed(frf: FrfEstimate, wide: MultiFit) -> tuple[MultiFit, tuple[float, ...]]:
    """The poles found over the wide band, refitted over +-2.5 of their bandwidths (inside it), and
    per pole how far the frequency moved: the straight line stands in for the far modes less well
    over a wider band, so the move measures what the model leaves (a model-error term)."""
    bw = [
        2 * z * f + 1.0 / (math.pi * frf.tau_s)
        for f, z in zip(wide.frequencies_hz, wide.damping_ratios, strict=True)
    ]
    f_lo = min(f - max(2.5 * b, 4.0 * frf.df) for f, b in zip(wide.frequencies_hz, bw, strict=True))
    f_hi = max(f + max(2.5 * b, 4.0 * frf.df) for f, b in zip(wide.frequencies_hz, bw, strict=True))
    lo = max(wide.bins[0], math.floor(f_lo / frf.df))
    hi = min(wide.bins[1], math.ceil(f_hi / frf.df) + 1)
    narrow = _fit(frf, list(wide.poles), (lo, hi)) if (lo, hi) != wide.bins else None
    if narrow is None or len(narrow.poles) != len(wide.poles):
        return wide, tuple(0.0 for _ in wide.poles)
    moved = tuple(abs(a - b) for a, b in zip(narrow.frequencies_hz, wide.frequencies_hz, strict=True))
    return narrow, moved


def _unresolved(
    frf: FrfEstimate, peaks: list[Peak], members: list[int], joint: MultiFit, hint: MultiFit
) -> list[ModeFit]:
    """The fit's residual shows another pole that cannot be separated: each frequency gets as a
    model-error term how far the extra pole moves it, and a warning names the frequencies."""
    moved = tuple(min(abs(f - g) for g in hint.frequencies_hz) for f in joint.frequencies_hz)
    extra = [g for g in hint.frequencies_hz if min(abs(g - f) for f in joint.frequencies_hz) > 0.5 * frf.df]
    shown = ", ".join(f"{f:.1f}" for f in sorted([*joint.frequencies_hz, *extra]))
    note = (
        f"the peak at {joint.frequencies_hz[0]:.1f} Hz looks like close modes ({shown} Hz"
        f"{'' if extra else ' and one within 1/T of it'}) that this record cannot separate"
        f" (resolution 1/T = {frf.df:.3g} Hz): its uncertainty includes the difference;"
        f" record longer per hit to separate them"
    )
    fits = _modes_of(frf, peaks, members, joint, moved)
    return [replace(m, note=note if i == 0 else "", unresolved=True) for i, m in enumerate(fits)]


def _modes_of(
    frf: FrfEstimate,
    peaks: list[Peak],
    members: list[int],
    fit: MultiFit,
    u_model: tuple[float, ...] | None = None,
) -> list[ModeFit]:
    """One ModeFit per pole; each found peak goes with its nearest pole, the others are hidden poles."""
    per_hit = _per_hit(frf, fit)
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
