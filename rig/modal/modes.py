"""Modes from the FRFs: peaks, a single-mode fit for frequency and damping, and the pole's residues.

Peaks: of the mode indicator |H1|^2 + |H2|^2 inside the analysis band, with a minimum prominence
(in decades) and height. Each peak gets:
1. a half-power estimate: the band where the indicator stays above half its peak value gives
   f and zeta_hp = bandwidth / (2 f) - 1/(tau omega) (the exponential window's share removed);
2. a fit, jointly to both FRFs over a band around the peak, of one mode in pole-residue form as
   the sampled, windowed impulse response gives it:
       H(k) = R / (1 - exp((p - s_k) dt)) + conj(R) / (1 - exp((conj(p) - s_k) dt)) + C + D x_k
   with s_k = j omega_k + 1/tau (the exponential window; frf.py), the pole p = -sigma + j omega_d
   shared, and per FRF a complex residue R and a straight line C + D x_k for the other modes.
   Variable projection: the linear coefficients are solved for each trial pole, the pole by
   scipy.optimize.least_squares; the Jacobian gives the fit's standard uncertainty, scaled by
   the square root of the window's equivalent noise bandwidth in bins (about 1.5 for exp_end
   0.01), since the exponential window correlates the noise of neighbouring bins.
   f_n = |p| / 2 pi, zeta = sigma / |p|. If the fit fails, the half-power values stand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import find_peaks

from rig.modal.frf import FrfEstimate

MIN_FIT_BINS = 7


@dataclass(frozen=True)
class Peak:
    """A peak of the mode indicator and its half-power estimate."""

    index: int  # bin
    frequency_hz: float
    bandwidth_hz: float  # half-power bandwidth as measured (window damping included)
    damping_hp: float  # half-power damping ratio, exponential window's share removed
    rise: float = math.inf  # sqrt of the indicator at the peak minus at the higher of its two bases


@dataclass(frozen=True)
class PoleFit:
    """A single-mode fit: natural frequency, damping, residues at both accelerometers."""

    frequency_hz: float
    damping_ratio: float
    residues: tuple[complex, complex]
    u_frequency_hz: float  # standard uncertainty from the fit (Jacobian)
    bins: tuple[int, int]  # fitted bin range [lo, hi)
    method: str  # "pole fit" or "half-power"


def mode_indicator(frf: FrfEstimate) -> np.ndarray:
    """|H1|^2 + |H2|^2."""
    return np.sum(np.abs(frf.h) ** 2, axis=0)


def find_mode_peaks(
    frf: FrfEstimate, band: tuple[float, float], prominence_decades: float, height_decades: float
) -> list[Peak]:
    """Peaks of the mode indicator inside `band` (Hz), lowest frequency first."""
    mif = mode_indicator(frf)
    inside = np.flatnonzero((frf.freq_hz >= band[0]) & (frf.freq_hz <= band[1]))
    if inside.size < 3:
        return []
    seg = np.log10(np.maximum(mif[inside], np.finfo(float).tiny))
    idx, props = find_peaks(seg, prominence=prominence_decades, height=seg.max() - height_decades)
    peaks = []
    for i, left, right in zip(idx, props["left_bases"], props["right_bases"], strict=True):
        k = int(inside[i])
        base = max(mif[inside[left]], mif[inside[right]])
        peaks.append(replace(_half_power(frf, mif, k), rise=float(math.sqrt(mif[k]) - math.sqrt(base))))
    return peaks


def _crossing(freq: np.ndarray, mif: np.ndarray, k: int, level: float, step: int) -> float:
    j = k
    while 0 < j < mif.size - 1 and mif[j] >= level:
        j += step
    a, b = (j, j - step)  # a below the level, b above it
    if mif[a] >= level or mif[b] == mif[a]:
        return float(freq[j])
    return float(freq[a] + (level - mif[a]) * (freq[b] - freq[a]) / (mif[b] - mif[a]))


def _half_power(frf: FrfEstimate, mif: np.ndarray, k: int) -> Peak:
    # refine the bin by a parabola through log power at k-1, k, k+1
    f = frf.freq_hz
    fk = float(f[k])
    if 0 < k < mif.size - 1:
        y0, y1, y2 = np.log(mif[k - 1 : k + 2])
        den = y0 - 2 * y1 + y2
        if den < 0:
            fk += 0.5 * (y0 - y2) / den * frf.df
    level = 0.5 * mif[k]
    lo = _crossing(f, mif, k, level, -1)
    hi = _crossing(f, mif, k, level, +1)
    bw = max(hi - lo, frf.df)
    zeta = bw / (2.0 * fk) - 1.0 / (frf.tau_s * 2 * math.pi * fk)
    return Peak(k, fk, bw, max(zeta, 0.0))


def fit_band(frf: FrfEstimate, peaks: list[Peak], i: int) -> tuple[int, int]:
    """Bins [lo, hi) fitted around peak i: +-2.5 bandwidths, at least 4 bins, halfway to neighbours."""
    p = peaks[i]
    half = max(2.5 * p.bandwidth_hz, 4.0 * frf.df) / frf.df
    lo = p.index - half
    hi = p.index + half
    if i > 0:
        lo = max(lo, 0.5 * (peaks[i - 1].index + p.index))
    if i + 1 < len(peaks):
        hi = min(hi, 0.5 * (peaks[i + 1].index + p.index))
    lo_i = max(1, math.floor(lo))
    hi_i = min(frf.freq_hz.size, math.ceil(hi) + 1)
    while hi_i - lo_i < MIN_FIT_BINS and (lo_i > 1 or hi_i < frf.freq_hz.size):
        lo_i, hi_i = max(1, lo_i - 1), min(frf.freq_hz.size, hi_i + 1)
    return lo_i, hi_i


def _basis(pole: complex, s: np.ndarray, dt: float, x: np.ndarray) -> np.ndarray:
    g1 = 1.0 / -np.expm1((pole - s) * dt)
    g2 = 1.0 / -np.expm1((np.conj(pole) - s) * dt)
    one = np.ones_like(x)
    cols = [g1 + g2, 1j * (g1 - g2), one, 1j * one, x, 1j * x]
    a = np.stack(cols, axis=1)
    return np.vstack([a.real, a.imag])  # real coefficients, real and imaginary parts stacked


def fit_pole(
    h: np.ndarray, s: np.ndarray, dt: float, guess: complex, df: float
) -> tuple[complex, tuple[complex, complex], float] | None:
    """Fit one pole to the FRFs h (2 or more, K) sampled at s (K,); returns pole, residues, u(f_n) or None."""
    w0 = abs(guess)
    omega = s.imag
    x = (omega - omega.mean()) / w0
    y = [np.concatenate([hi.real, hi.imag]) for hi in h]
    scale = [float(np.max(np.abs(hi))) or 1.0 for hi in h]

    def solve(theta: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        pole = complex(-theta[0] * w0, theta[1] * w0)
        a = _basis(pole, s, dt, x)
        coefs, res = [], []
        for yi, sc in zip(y, scale, strict=True):
            c, *_ = np.linalg.lstsq(a, yi / sc, rcond=None)
            coefs.append(c * sc)
            res.append(a @ c - yi / sc)
        return np.concatenate(res), coefs

    lo, hi = omega.min() / w0, omega.max() / w0
    theta0 = np.array([max(-guess.real / w0, 1e-6), min(max(guess.imag / w0, lo), hi)])

    def residuals(theta: np.ndarray) -> np.ndarray:
        return solve(theta)[0]

    try:
        out = least_squares(residuals, theta0, bounds=([0.0, lo], [0.5, hi]), x_scale=[1e-3, 1e-3])
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not out.success or not np.all(np.isfinite(out.x)):
        return None
    sigma, wd = out.x * w0
    if not lo * w0 < wd < hi * w0:
        return None
    pole = complex(-sigma, wd)
    _, coefs = solve(out.x)
    residues = (complex(coefs[0][0], coefs[0][1]), complex(coefs[1][0], coefs[1][1]))
    m, n_par = out.fun.size, 2 + 6 * len(h)  # the pole, and 6 linear terms per channel
    u_fn = df / math.sqrt(12.0)
    if m > n_par:
        s2 = 2.0 * out.cost / (m - n_par)
        try:
            jac = np.asarray(out.jac)  # dense: no jac_sparsity, the default trust-region solver
            cov = s2 * np.linalg.inv(jac.T @ jac)
        except np.linalg.LinAlgError:
            cov = None
        if cov is not None and np.all(np.isfinite(cov)):
            grad = np.array([sigma, wd]) / abs(pole) * w0  # d|p|/d theta
            u_fn = math.sqrt(max(float(grad @ cov @ grad), 0.0)) / (2 * math.pi)
    return pole, residues, u_fn


def fit_mode(frf: FrfEstimate, peak: Peak, bins: tuple[int, int], h: np.ndarray | None = None) -> PoleFit:
    """Fit one mode over `bins` of the averaged FRFs (or of `h`, e.g. one hit's); half-power if it fails."""
    lo, hi = bins
    data = (frf.h if h is None else h)[:, lo:hi]
    wn = 2 * math.pi * peak.frequency_hz
    guess = complex(-max(peak.damping_hp, 1e-4) * wn, wn)
    fitted = fit_pole(data, frf.s[lo:hi], frf.dt, guess, frf.df)
    if fitted is None:
        k = peak.index
        residues = (complex(frf.h[0, k]), complex(frf.h[1, k]))
        return PoleFit(
            peak.frequency_hz, peak.damping_hp, residues, frf.df / math.sqrt(12.0), bins, "half-power"
        )
    pole, residues, u_fn = fitted
    u_fn *= math.sqrt(max(frf.enbw_bins, 1.0))  # the fit took the bins as independent; they are not
    return PoleFit(abs(pole) / (2 * math.pi), -pole.real / abs(pole), residues, u_fn, bins, "pole fit")
