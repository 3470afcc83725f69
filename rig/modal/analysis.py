"""From a recording to the bat's modes and its first hoop frequency, with uncertainty.

Steps: channel checks (dead, clipped) -> hits (hits.py) -> resolution check -> H1 and coherence
(frf.py) -> peaks and mode fits, close ones jointly (modes.py, multipole.py) -> classification
-> per-hit spread -> result.

A peak is a mode only if it stands clear of the noise: its |H| rises above its bases by min_snr
standard deviations of the FRF's noise (from the accelerometers' noise before the first hit), and
with two or more hits its coherence reaches mode_coherence on one accelerometer at least. A peak
dropped for low coherence below the first hoop mode, where the FRFs overlay, is LowCoherence: it
could be the real first hoop mode.

Classification (the founding paper, section 4.1): at a hoop mode the FRFs of the two
accelerometers overlay, |R1|/|R2| within 1/hoop_ratio..hoop_ratio (R: the fitted residues, the
modal constants at each accelerometer); a bending mode shows mainly on accelerometer 1, in line
with the hammer: |R1|/|R2| >= bending_ratio. Anything else is "unclassified".

Uncertainty of a mode's frequency (standard, k = 1; `U` is k = 2):
  u^2 = u_res^2 + u_fit^2 + u_spread^2 + u_model^2
  u_res    = RESOLUTION_SHARE x df / sqrt(12), df = 1/T the resolution: what the finite window
             leaves in a fitted frequency (benchmarks/bench_modal.py: the largest noise-free
             error is about 0.005 df, U_res = 0.058 df); the full df / sqrt(12) if the fit failed;
  u_fit    = from the fit's Jacobian and residuals (modes.py);
  u_spread = standard deviation of the per-hit fitted frequencies / sqrt(hits) (0 for one hit);
  u_model  = where the fit's residual exceeds the noise (multipole.py): how far the frequency moves
             between two fit bands, or how far an unseparable second pole moves it; else 0.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from rig.core.errors import ParameterError
from rig.modal import frf as frf_mod
from rig.modal.errors import LowCoherence, RecordTooShort
from rig.modal.hits import QUIET_MIN, Hits, check_channels, pulse_guard, segment
from rig.modal.modes import PoleFit, find_mode_peaks
from rig.modal.multipole import ModeFit, fit_modes
from rig.modal.output_only import output_only_kinds
from rig.modal.recording import Recording

RESOLUTION_SHARE = 0.1
COVERAGE_K = 2.0
RATIO_CAP = 1e6
# The band's default lower edge: a mode needs a few resolution bins below it to be fitted (and a few
# cycles in the window); the floor keeps the suspension's bounce (a few Hz on bungee cords) out.
BAND_MIN_BINS = 3.0
BAND_FLOOR_HZ = 10.0


@dataclass(frozen=True)
class ModalSettings:
    """Analysis settings; every default is documented in docs/modal.md."""

    threshold_sigma: float = 10.0  # pulse threshold, multiples of the force noise
    threshold_fraction: float = 0.02  # ... and at least this fraction of the largest pulse
    min_force_snr: float = 20.0  # every pulse must peak at this many times the force noise
    pretrigger_s: float = 1e-3
    window_s: float | None = None  # None: as long as the spacing of the hits allows
    min_spacing_s: float = 0.05  # with automatic windows: a second pulse sooner is a double hit
    exp_end: float = 0.01  # exponential window's value at the end of the window
    max_resolution_hz: float = 20.0  # refuse windows giving a coarser resolution 1/T
    f_min_hz: float | None = None  # band's lower edge; None: BAND_MIN_BINS / T, at least BAND_FLOOR_HZ
    f_max_hz: float | None = None  # band's upper edge; None: where the hammer's spectrum has dropped
    force_drop_db: float = 20.0  # analysis band ends where the hammer spectrum has dropped this much
    prominence_decades: float = 0.5  # peaks of |H1|^2 + |H2|^2: prominence, log10 units
    height_decades: float = 4.0  # ... and within this of the highest peak
    hoop_ratio: float = 2.0
    bending_ratio: float = 4.0
    min_coherence: float = 0.9  # at the first hoop mode, with two or more hits
    mode_coherence: float = 0.5  # a peak with less on both accelerometers is noise (two or more hits)
    min_snr: float = 5.0  # a peak's |H| must rise above its bases by this many FRF noise std
    clip_run: int = 3
    ringing_fraction: float = 0.02  # warn if a hit comes while the last one still rings this much

    def __post_init__(self) -> None:
        positive = (
            "threshold_sigma",
            "pretrigger_s",
            "min_spacing_s",
            "max_resolution_hz",
            "f_min_hz",
            "f_max_hz",
        )
        for name in positive:
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ParameterError(name, value, "must be finite and > 0")
        if self.f_min_hz is not None and self.f_max_hz is not None and self.f_max_hz <= self.f_min_hz:
            raise ParameterError("f_max_hz", self.f_max_hz, f"must be above f_min_hz ({self.f_min_hz:g})")
        if self.window_s is not None and not self.window_s > 0:
            raise ParameterError("window_s", self.window_s, "must be > 0")
        if not 0 < self.exp_end <= 1:
            raise ParameterError("exp_end", self.exp_end, "must be in (0, 1]")
        if not 0 <= self.threshold_fraction < 1:
            raise ParameterError("threshold_fraction", self.threshold_fraction, "must be in [0, 1)")
        if not 1 < self.hoop_ratio <= self.bending_ratio:
            raise ParameterError("hoop_ratio", self.hoop_ratio, "must be > 1 and <= bending_ratio")
        if not 0 <= self.min_coherence <= 1:
            raise ParameterError("min_coherence", self.min_coherence, "must be in [0, 1]")


@dataclass(frozen=True)
class Mode:
    """One identified mode."""

    frequency_hz: float
    damping_ratio: float
    kind: str  # "hoop", "bending" or "unclassified"
    accelerometers: tuple[str, ...]
    magnitude_ratio: float  # |R1| / |R2|, capped at RATIO_CAP
    phase_deg: float  # angle of R2 relative to R1
    coherence: float  # the lowest over the accelerometers it shows on
    coherence_accel1: float
    coherence_accel2: float
    u_hz: float
    u_resolution_hz: float
    u_fit_hz: float
    u_spread_hz: float
    per_hit_hz: tuple[float, ...]
    method: str  # "pole fit" or "half-power"
    u_model_hz: float = 0.0  # close modes: how far the joint fit's frequency moves between two bands

    @property
    def expanded_uncertainty_hz(self) -> float:
        """U = k u with k = 2."""
        return COVERAGE_K * self.u_hz

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        d = asdict(self)
        d["accelerometers"] = list(self.accelerometers)
        d["per_hit_hz"] = list(self.per_hit_hz)
        d["expanded_uncertainty_hz"] = self.expanded_uncertainty_hz
        d["coverage_k"] = COVERAGE_K
        return d


@dataclass(frozen=True, eq=False)
class ModalResult:
    """The analysis of one recording."""

    modes: tuple[Mode, ...]
    n_hits: int
    hit_times_s: tuple[float, ...]
    window_s: float
    resolution_hz: float
    sample_rate_hz: float
    band_hz: tuple[float, float]
    tau_s: float
    noise_n: float
    threshold_n: float
    warnings: tuple[str, ...]
    settings: ModalSettings
    frf: frf_mod.FrfEstimate = field(repr=False)
    source: str = ""
    accel_noise: tuple[float, float] | None = None  # noise std of each accelerometer, m/s^2
    noise_source: str | None = None  # "before the first hit", "tail" or None

    @property
    def hoop(self) -> Mode | None:
        """The first (lowest) hoop mode, if any."""
        return next((m for m in self.modes if m.kind == "hoop"), None)

    @property
    def hoop_hz(self) -> float | None:
        """First hoop frequency, Hz."""
        return None if self.hoop is None else self.hoop.frequency_hz

    @property
    def bending_hz(self) -> list[float]:
        """Bending frequencies, ascending."""
        return [m.frequency_hz for m in self.modes if m.kind == "bending"]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary: hoop_hz, bending_hz, per-mode details, how it was measured."""
        hoop = self.hoop
        return {
            "source": self.source,
            "hoop_hz": self.hoop_hz,
            "hoop_u_hz": None if hoop is None else hoop.u_hz,
            "hoop_expanded_uncertainty_hz": None if hoop is None else hoop.expanded_uncertainty_hz,
            "bending_hz": self.bending_hz,
            "modes": [m.as_dict() for m in self.modes],
            "n_hits": self.n_hits,
            "hit_times_s": list(self.hit_times_s),
            "window_s": self.window_s,
            "resolution_hz": self.resolution_hz,
            "sample_rate_hz": self.sample_rate_hz,
            "band_hz": list(self.band_hz),
            "exponential_window_tau_s": self.tau_s,
            "force_noise_n": self.noise_n,
            "force_threshold_n": self.threshold_n,
            "accel_noise_ms2": None if self.accel_noise is None else list(self.accel_noise),
            "accel_noise_from": self.noise_source,
            "warnings": list(self.warnings),
            "settings": asdict(self.settings),
        }


def _coherence(frf: frf_mod.FrfEstimate, f_hz: float, half_bw: float) -> tuple[float, float]:
    near = np.abs(frf.freq_hz - f_hz) <= max(half_bw, 0.5 * frf.df)
    if not near.any():
        near = np.zeros(frf.freq_hz.size, dtype=bool)
        near[int(np.argmin(np.abs(frf.freq_hz - f_hz)))] = True
    c = frf.coherence[:, near].mean(axis=1)
    return float(c[0]), float(c[1])


def _classify(ratio: float, s: ModalSettings) -> tuple[str, tuple[str, ...]]:
    if 1.0 / s.hoop_ratio <= ratio <= s.hoop_ratio:
        return "hoop", ("accel1", "accel2")
    if ratio >= s.bending_ratio:
        return "bending", ("accel1",)
    return "unclassified", ("accel1", "accel2") if ratio >= 1.0 / s.bending_ratio else ("accel2",)


def _mode(frf: frf_mod.FrfEstimate, mf: ModeFit, s: ModalSettings) -> Mode:
    fit, peak, per_hit = mf.fit, mf.peak, list(mf.per_hit_hz)
    r1, r2 = fit.residues
    ratio = min(abs(r1) / abs(r2), RATIO_CAP) if abs(r2) * RATIO_CAP > abs(r1) else RATIO_CAP
    kind, accels = _classify(ratio, s)
    phase = math.degrees(np.angle(r2 / r1)) if abs(r1) > 0 else 0.0
    c1, c2 = _coherence(frf, fit.frequency_hz, 0.5 * peak.bandwidth_hz)
    coh = min(c for c, name in ((c1, "accel1"), (c2, "accel2")) if name in accels)
    u_spread = float(np.std(per_hit, ddof=1) / math.sqrt(len(per_hit))) if len(per_hit) >= 2 else 0.0
    u_res = RESOLUTION_SHARE * frf.df / math.sqrt(12.0)
    if fit.method != "pole fit":
        u_res = frf.df / math.sqrt(12.0)
    u = math.sqrt(u_res**2 + fit.u_frequency_hz**2 + u_spread**2 + mf.u_model_hz**2)
    return Mode(
        frequency_hz=fit.frequency_hz,
        damping_ratio=fit.damping_ratio,
        kind=kind,
        accelerometers=accels,
        magnitude_ratio=float(ratio),
        phase_deg=float(phase),
        coherence=float(coh),
        coherence_accel1=c1,
        coherence_accel2=c2,
        u_hz=u,
        u_resolution_hz=u_res,
        u_fit_hz=fit.u_frequency_hz,
        u_spread_hz=u_spread,
        per_hit_hz=tuple(per_hit),
        method=fit.method,
        u_model_hz=mf.u_model_hz,
    )


def analyze_hits(rec: Recording, hits: Hits, settings: ModalSettings) -> ModalResult:
    """The modes of a recording whose hits are already found."""
    s = settings
    name = rec.source or "recording"
    window_s = hits.window_n * rec.dt
    df = 1.0 / window_s
    if df > s.max_resolution_hz:
        raise RecordTooShort(
            f"{name}: the hit windows are {window_s * 1e3:.1f} ms long, a resolution of {df:.3g} Hz;"
            f" the analysis needs <= {s.max_resolution_hz:g} Hz: record at least"
            f" {1e3 / s.max_resolution_hz:.0f} ms after each hit (and leave that long between hits)"
        )
    frf = frf_mod.estimate(rec, hits, s.exp_end)
    band = analysis_band(frf, s, rec.fs)
    warnings = list(hits.dropped) + _still_ringing(rec, hits, s.ringing_fraction)
    peaks = find_mode_peaks(frf, band, s.prominence_decades, s.height_decades)
    modes, noise_peaks, buried, clear, blends = [], [], [], [], []
    for peak in peaks:
        if frf.noise_h is not None:
            noise = math.sqrt(float(np.sum(frf.noise_h[:, peak.index] ** 2)))
            if peak.rise < s.min_snr * noise:
                buried.append(peak.frequency_hz)
                continue
        clear.append(peak)
    # one hit: the residual's structure cannot be told from noise (no coherence, no spread), and
    # the search made up modes beside the bending modes, read as hoop (15 of 48 noisy records)
    for mf in fit_modes(frf, clear, check_order=hits.count >= 2):
        if mf.note:
            warnings.append(mf.note)
        c1, c2 = _coherence(frf, mf.fit.frequency_hz, 0.5 * mf.peak.bandwidth_hz)
        if hits.count >= 2 and max(c1, c2) < s.mode_coherence:
            noise_peaks.append((mf.fit, max(c1, c2)))  # a peak of the noise, not of the bat
            continue
        modes.append(_mode(frf, mf, s))
        if mf.unresolved:
            blends.append(modes[-1])
    modes.sort(key=lambda m: m.frequency_hz)
    modes = _without_mains(modes, warnings)
    if rec.responses == 1:  # one response (a two-channel WAV): no magnitude ratio to classify by
        kinds = output_only_kinds([m.frequency_hz for m in modes], [m.damping_ratio for m in modes])
        modes = [replace(m, kind=k, accelerometers=("accel1",)) for m, k in zip(modes, kinds, strict=True)]
        warnings.append(
            "one response: the hoop mode is told from bending modes by its position and damping"
            " (rig.modal.output_only), not by two accelerometers 90 degrees apart"
        )
    _check_noise_peaks(name, noise_peaks, modes, s, warnings)
    if buried:
        warnings.append(
            f"{len(buried)} peak(s) not clear of the FRF's noise"
            f" (rise < {s.min_snr:g} x noise std) ignored: {_listed(buried)} Hz"
        )
    elif frf.noise_h is None:
        warnings.append(
            f"no noise level: fewer than {QUIET_MIN} quiet samples before the first hit and a window too"
            f" short for its tail: peaks not tested against the noise level"
        )
    hoop = next((m for m in modes if m.kind == "hoop"), None)
    for m in blends:
        if m.kind != "hoop" and (hoop is None or m.frequency_hz < hoop.frequency_hz):
            warnings.append(
                f"the {m.kind} mode at {m.frequency_hz:.1f} Hz blends two modes this record cannot separate"
                f" (|H1|/|H2| {m.magnitude_ratio:.3g}): the first hoop mode may be there, not "
                + ("absent" if hoop is None else f"at {hoop.frequency_hz:.1f} Hz")
                + "; record longer per hit"
            )
    on_two = [m for m in modes if m.magnitude_ratio <= 1.0 / s.bending_ratio]
    if on_two and not any(m.kind == "bending" for m in modes):
        warnings.append(
            f"{len(on_two)} mode(s) show mainly on accelerometer 2 and none on accelerometer 1"
            f" ({', '.join(f'{m.frequency_hz:.0f}' for m in on_two[:LISTED])} Hz): are the accelerometer"
            f" columns swapped? Accelerometer 1 must be the one in line with the hammer"
        )
    if s.f_min_hz is not None:
        lo_default = default_band_min(frf.df)
        if s.f_min_hz > lo_default:
            warnings.append(
                f"the band starts at {band[0]:.0f} Hz as set (default {lo_default:.0f} Hz): a hoop mode"
                f" below it would not be seen, and the first hoop reported is the first in the band"
            )
    if hoop is None:
        listed = ", ".join(f"{m.frequency_hz:.0f} Hz (|H1|/|H2| {m.magnitude_ratio:.3g})" for m in modes)
        warnings.append(
            f"no hoop mode: no peak where the two FRFs overlay (|H1|/|H2| within 1/{s.hoop_ratio:g}"
            f"..{s.hoop_ratio:g}) in {band[0]:.0f}-{band[1]:.0f} Hz; modes: {listed or 'none'}"
        )
    elif hits.count < 2:
        warnings.append(
            "one hit: coherence is 1 by construction and modes hidden in a neighbour's peak are not"
            " searched for; average two or more hits to check both"
        )
    elif hoop.coherence < s.min_coherence:
        raise LowCoherence(
            f"{name}: coherence {hoop.coherence:.3f} at the hoop mode {hoop.frequency_hz:.1f} Hz is below"
            f" {s.min_coherence:g} (accelerometer 1: {hoop.coherence_accel1:.3f}, 2:"
            f" {hoop.coherence_accel2:.3f}): noise, a loose accelerometer, or hits that differ; record again"
        )
    for m in modes:
        if m.kind != "hoop" and hits.count >= 2 and m.coherence < s.min_coherence:
            warnings.append(f"low coherence {m.coherence:.2f} at the {m.kind} mode {m.frequency_hz:.1f} Hz")
    return ModalResult(
        modes=tuple(modes),
        n_hits=hits.count,
        hit_times_s=tuple(float(rec.time_s[p.start]) for p in hits.pulses),
        window_s=window_s,
        resolution_hz=df,
        sample_rate_hz=rec.fs,
        band_hz=band,
        tau_s=frf.tau_s,
        noise_n=hits.noise_n,
        threshold_n=hits.threshold_n,
        warnings=tuple(warnings),
        settings=s,
        frf=frf,
        source=rec.source,
        accel_noise=hits.accel_noise,
        noise_source=hits.noise_source,
    )


def default_band_min(df: float) -> float:
    """The band's default lower edge for resolution `df`: BAND_MIN_BINS bins, at least BAND_FLOOR_HZ."""
    return max(BAND_MIN_BINS * df, BAND_FLOOR_HZ)


def analysis_band(frf: frf_mod.FrfEstimate, s: ModalSettings, fs: float) -> tuple[float, float]:
    """The band searched for modes: from f_min_hz (default BAND_MIN_BINS resolutions, at least
    BAND_FLOOR_HZ) to f_max_hz (default where the hammer's spectrum has dropped force_drop_db),
    never below two resolutions nor above 0.45 fs."""
    lo = s.f_min_hz if s.f_min_hz is not None else default_band_min(frf.df)
    hi = s.f_max_hz if s.f_max_hz is not None else frf_mod.force_band(frf, s.force_drop_db)
    return max(lo, 2.0 * frf.df), min(hi, 0.45 * fs)


# Mains interference: a sine at a multiple of 50 or 60 Hz reads as a mode without damping. No bat
# mode is that undamped (hoop and bending modes: zeta 0.001-0.02), and none sits within this of a
# multiple of the mains frequency by chance often enough to matter.
MAINS_HZ = (50.0, 60.0)
MAINS_TOLERANCE_HZ = 0.5
MAINS_MAX_DAMPING = 2e-4
LISTED = 12  # frequencies listed in a warning; the rest are counted


def _without_mains(modes: list[Mode], warnings: list[str]) -> list[Mode]:
    """Modes less those that are mains hum (undamped, at a multiple of 50 or 60 Hz), with a warning."""
    hum = [
        m
        for m in modes
        if m.damping_ratio < MAINS_MAX_DAMPING
        and any(
            abs(m.frequency_hz - n * base) <= MAINS_TOLERANCE_HZ
            for base in MAINS_HZ
            for n in range(1, 1 + int(m.frequency_hz // base) + 1)
        )
    ]
    if hum:
        warnings.append(
            "mains interference left out: "
            + ", ".join(f"{m.frequency_hz:.2f} Hz (damping {m.damping_ratio:.1e})" for m in hum)
            + ", undamped at a multiple of 50 or 60 Hz: check the grounding and shielding of the"
            " sensor cables"
        )
    return [m for m in modes if m not in hum]


def _listed(freqs: list[float]) -> str:
    """Frequencies for a warning: the first LISTED, and a count of the rest."""
    shown = ", ".join(f"{f:.0f}" for f in freqs[:LISTED])
    return shown if len(freqs) <= LISTED else f"{shown} and {len(freqs) - LISTED} more up to {max(freqs):.0f}"


def _still_ringing(rec: Recording, hits: Hits, fraction: float) -> list[str]:
    """Hits that came while the bat still rang from the one before (it lowers the coherence).

    The ringing is what the samples just before a hit hold beyond the accelerometer's noise: their
    mean square less sigma^2, counted only where it exceeds sigma^2 by more than chance does (four
    standard deviations of a mean of m squared Gaussian samples, 4 sqrt(2/m) sigma^2).
    """
    sigma = 0.0 if hits.accel_noise is None else hits.accel_noise[0]
    guard = pulse_guard(rec.fs)
    worst, which = 0.0, 0
    for k in range(1, hits.count):
        a, p = hits.starts[k], hits.pulses[k]
        # stop short of the threshold crossing: the pulse (and the response) rose before it
        before = rec.accel1[a : p.start - guard] - np.median(rec.accel1)
        peak = float(np.max(np.abs(rec.accel1[a : a + hits.window_n])))
        if before.size and peak > 0:
            power = float(np.mean(before**2))
            if power <= sigma**2 * (1.0 + 4.0 * math.sqrt(2.0 / before.size)):
                continue  # noise, not ringing
            level = math.sqrt(power - sigma**2) / peak
            if level > worst:
                worst, which = level, k
    if worst <= fraction:
        return []
    return [
        f"the bat still rang when hit {which + 1} came ({100 * worst:.1f}% of that hit's peak on"
        f" accelerometer 1 before it): leave more time between hits"
    ]


def _check_noise_peaks(
    name: str,
    noise_peaks: list[tuple[PoleFit, float]],
    modes: list[Mode],
    s: ModalSettings,
    warnings: list[str],
) -> None:
    """Peaks dropped for coherence below mode_coherence: one that could be the first hoop mode is fatal."""
    if not noise_peaks:
        return
    first_hoop = next((m.frequency_hz for m in modes if m.kind == "hoop"), math.inf)
    for fit, coh in noise_peaks:
        r1, r2 = fit.residues
        overlay = abs(r2) > 0 and 1.0 / s.hoop_ratio <= abs(r1) / abs(r2) <= s.hoop_ratio
        if overlay and fit.frequency_hz < first_hoop:
            raise LowCoherence(
                f"{name}: a peak at {fit.frequency_hz:.1f} Hz where the two FRFs overlay (a hoop mode?)"
                f" has coherence {coh:.3f}, too low to tell a mode from noise: noise, a loose"
                f" accelerometer, or hits that differ; record again"
            )
    freqs = ", ".join(f"{fit.frequency_hz:.0f}" for fit, _ in noise_peaks)
    warnings.append(
        f"{len(noise_peaks)} peak(s) ignored as noise (coherence < {s.mode_coherence:g}): {freqs} Hz"
    )


def analyze(rec: Recording, settings: ModalSettings | None = None) -> ModalResult:
    """Check the recording, find the hits, estimate the FRFs and identify the modes."""
    s = settings or ModalSettings()
    check_channels(rec, s.clip_run)
    hits = segment(
        rec,
        threshold_sigma=s.threshold_sigma,
        threshold_fraction=s.threshold_fraction,
        pretrigger_s=s.pretrigger_s,
        window_s=s.window_s,
        min_spacing_s=s.min_spacing_s,
        min_force_snr=s.min_force_snr,
    )
    return analyze_hits(rec, hits, s)
