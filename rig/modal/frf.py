"""H1 frequency-response estimate averaged over hits, with coherence.

Per hit, over one window of N samples from the pre-trigger on:
- every channel loses its baseline (the channel's median over the record);
- force window: the force is kept up to the end of its pulse plus a margin (one pulse length,
  at least FORCE_MARGIN_S) and set to zero after it, so the force channel's noise after the
  impact does not enter the spectrum;
- exponential window w(t) = exp(-t/tau) on force and responses alike, tau set so that w falls to
  `exp_end` at the window's end: the response has decayed by then, so the window does not leak.
  Because w(t) = w(u) w(t - u), the windowed response is the windowed impulse response convolved
  with the windowed force: the estimate is exactly the FRF at s = j omega + 1/tau, i.e. every
  pole's decay rate grows by 1/tau. The mode fit (modes.py) evaluates its model at that s, so
  it returns the bat's own damping; the half-power estimate is corrected by 1/tau likewise.
Averaged over hits: Gff = mean |F|^2, Gxf = mean conj(F) X, Gxx = mean |X|^2;
H1 = Gxf / Gff and coherence = |Gxf|^2 / (Gff Gxx) (1 by construction with one hit).
The FRF's noise level per bin follows from each accelerometer's noise before the first hit
(white noise of std sigma): std(H1) = sigma sqrt(sum w^2 / (hits Gff)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft

from rig.modal.hits import Hits
from rig.modal.recording import Recording

FORCE_MARGIN_S = 5e-4


@dataclass(frozen=True, eq=False)
class FrfEstimate:
    """FRFs of both accelerometers per unit hammer force ((m/s^2)/N) on the DFT bins of one window."""

    freq_hz: np.ndarray  # (K,)
    h: np.ndarray  # (2, K) complex: H1 of accelerometer 1 and 2
    coherence: np.ndarray  # (2, K)
    g_ff: np.ndarray  # (K,) mean force auto-spectrum |F|^2 (unscaled)
    per_hit: np.ndarray  # (hits, 2, K) complex: X/F of each hit
    dt: float
    window_n: int
    tau_s: float  # exponential window's time constant
    noise_h: np.ndarray | None = None  # (2, K) std of the FRF's noise, from the quiet samples

    @property
    def df(self) -> float:
        """Frequency resolution 1/T of the window, Hz."""
        return 1.0 / (self.window_n * self.dt)

    @property
    def n_hits(self) -> int:
        """Number of hits averaged."""
        return int(self.per_hit.shape[0])

    @property
    def enbw_bins(self) -> float:
        """Equivalent noise bandwidth of the exponential window in bins, N sum(w^2) / sum(w)^2:
        noise in neighbouring bins is correlated over about this many bins."""
        w = np.exp(-np.arange(self.window_n) * self.dt / self.tau_s)
        return float(self.window_n * np.sum(w * w) / np.sum(w) ** 2)

    @property
    def s(self) -> np.ndarray:
        """The complex frequency at which each bin samples the true FRF: j omega + 1/tau."""
        return 2j * math.pi * self.freq_hz + 1.0 / self.tau_s


def windows(rec: Recording, hits: Hits, exp_end: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Windowed force (hits, N) and responses (hits, 2, N), and tau."""
    n = hits.window_n
    t = np.arange(n) * rec.dt
    tau = n * rec.dt / math.log(1.0 / exp_end)
    w = np.exp(-t / tau)
    base = [float(np.median(rec.channel(c))) for c in ("accel1", "accel2")]
    margin = max(round(FORCE_MARGIN_S * rec.fs), 1)
    forces = np.empty((hits.count, n))
    resp = np.empty((hits.count, 2, n))
    for k, (a, pulse) in enumerate(zip(hits.starts, hits.pulses, strict=True)):
        f = rec.force[a : a + n] - hits.baseline_n
        keep = pulse.end - a + max(margin, pulse.end - pulse.start + 1)
        f = np.where(np.arange(n) <= keep, f, 0.0)
        forces[k] = f * w
        resp[k, 0] = (rec.accel1[a : a + n] - base[0]) * w
        resp[k, 1] = (rec.accel2[a : a + n] - base[1]) * w
    return forces, resp, tau


def estimate(rec: Recording, hits: Hits, exp_end: float) -> FrfEstimate:
    """H1 and coherence of both accelerometers, averaged over the hits."""
    forces, resp, tau = windows(rec, hits, exp_end)
    F = fft.rfft(forces, axis=-1)  # (hits, K)
    X = fft.rfft(resp, axis=-1)  # (hits, 2, K)
    g_ff = np.mean(np.abs(F) ** 2, axis=0)
    g_xf = np.mean(np.conj(F)[:, None, :] * X, axis=0)
    g_xx = np.mean(np.abs(X) ** 2, axis=0)
    tiny = np.finfo(float).tiny
    h = g_xf / np.maximum(g_ff, tiny)
    coh = np.abs(g_xf) ** 2 / np.maximum(g_ff * g_xx, tiny)
    per_hit = X / np.where(np.abs(F) > 0, F, tiny)[:, None, :]
    freq = fft.rfftfreq(hits.window_n, rec.dt)
    noise_h = None
    if hits.accel_noise is not None:
        # white noise of std sigma in a channel gives E|X_k|^2 = sigma^2 sum(w^2); averaged H1
        # then carries noise of variance sigma^2 sum(w^2) / (hits Gff)
        w2 = float(np.sum(np.exp(-2.0 * np.arange(hits.window_n) * rec.dt / tau)))
        sigma = np.asarray(hits.accel_noise)[:, None]
        noise_h = sigma * np.sqrt(w2 / (hits.count * np.maximum(g_ff, tiny)))[None, :]
    return FrfEstimate(freq, h, np.clip(coh, 0.0, 1.0), g_ff, per_hit, rec.dt, hits.window_n, tau, noise_h)


def force_band(frf: FrfEstimate, drop_db: float = 20.0) -> float:
    """The highest frequency up to which the hammer's spectrum stays within `drop_db` of its peak."""
    g = frf.g_ff
    level = g.max() * 10.0 ** (-drop_db / 10.0)
    below = np.flatnonzero(g[1:] < level)
    return float(frf.freq_hz[below[0]]) if below.size else float(frf.freq_hz[-1])
