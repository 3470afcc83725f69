"""The hoop frequency from a tap's ping: one channel, no force signal (output-only), several taps.

Steps (docs/screening.md):
1. checks: silent (at most SILENT_LEVELS sample values: silence, a constant, dither), clipped (3
   samples in a row at the record's extreme, or 4 at it in two places, or two samples at digital
   full scale), the noise floor, too quiet (the loudest tap less than MIN_SNR_DB
   above the floor). The floor is the lesser of two estimates that can only overstate it: the 10th
   percentile of 5 ms blocks' RMS (the quiet between taps) and the robust RMS of what a linear
   predictor of order PREDICTOR_ORDER cannot predict (a ring is predictable, noise is not: taps that
   ring into each other leave no quiet block, and the first estimate would take the ring for noise);
2. taps: an onset is a 1 ms block whose peak exceeds the threshold (max(30 x noise, 5 % of the
   loudest peak)) and 3 times the loudest of the 10 ms before it; onsets within MIN_SPACING_S of a
   tap are dropped with it (a bounce spoils the tap). Each tap's window starts SKIP_S after its
   onset (the free decay) and all have one length T: the shortest gap to the next onset less SKIP_S
   (a window ends before the next tap), at most MAX_WINDOW_S; T below MIN_WINDOW_S or fewer than
   MIN_TAPS taps is "too short";
3. spectra: each tap's window times w(t) = exp(-t/tau) (1 % at its end); a free decay's DFT is
   then exactly the pole-residue form rig.modal.modes fits, at s = j omega + 1/tau. The taps'
   power spectra summed give the peaks; each peak's pole is fitted jointly to every tap's complex
   spectrum (one shared pole, one residue per tap), and to each tap alone for the spread;
4. the first hoop mode by position, damping and strength (rig.modal.output_only);
5. u^2 = u_res^2 + u_fit^2 + u_spread^2 + u_model^2, as for impact tests (rig.modal.analysis), with
   u_model how far the frequency moves when the fit takes a band twice as wide (a room's
   reverberation, common to every tap, bends the peak away from one pole's shape) and u_room =
   ROOM_SHARE x the half-power bandwidth (what a room shifts in common) [assumed]; U = 2u.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy import fft, linalg, signal

from rig.modal.errors import ClippedSignal, NoHoopMode, RecordingFormatError, RecordTooShort, TooQuiet
from rig.modal.frf import FrfEstimate
from rig.modal.hits import longest_run, runs
from rig.modal.modes import find_mode_peaks, fit_band, fit_mode
from rig.modal.output_only import DAMPING_FACTOR, HOOP_MIN_HZ, MIN_AMPLITUDE, output_only_kinds
from rig.modal.wav import Wav

BLOCK_S = 1e-3
NOISE_BLOCK_S = 5e-3
LOOKBACK_S = 10e-3
ONSET_RISE = 3.0
MIN_SPACING_S = 0.05
SKIP_S = 0.02  # [assumed] the window starts after the contact and the early reflections of a room
MIN_WINDOW_S = 0.05  # a resolution of 20 Hz, as impact tests need
MAX_WINDOW_S = 0.5
MIN_TAPS = 3
MIN_SNR_DB = 40.0  # [assumed] the loudest tap over the noise floor
PREDICTOR_ORDER = 64  # taps of the linear predictor: two per mode for up to 32 modes
MAD_TO_SIGMA = 1.4826  # a normal distribution's sigma over its median absolute deviation
EXP_END = 0.01
RESOLUTION_SHARE = 0.1  # as rig.modal.analysis
COVERAGE_K = 2.0
FULL_SCALE = 0.9999
NEAR_RULE = 2.0  # a bending mode above HOOP_MIN_HZ within this times the damping limit is warned of
SILENT_LEVELS = 3  # a recording of at most this many sample values has no tap (silence, dither)
SILENT_SCAN = 65536  # samples looked at first (a recording with a tap has more levels in them)
PEAK_DECADES = 2.0  # peaks of the summed power within this of the highest (amplitude 10 %)
# [assumed] a room's reverberation, common to every tap, shifts a peak by up to about this share of
# its half-power bandwidth 2 zeta f (measured on the synthesized room of tests/modal/test_tap.py only)
ROOM_SHARE = 0.15


@dataclass(frozen=True)
class TapMode:
    """One mode of the ping."""

    frequency_hz: float
    damping_ratio: float
    kind: str
    amplitude: float  # sqrt of the summed power at the peak, relative to the loudest mode
    u_hz: float
    u_fit_hz: float
    u_spread_hz: float
    u_model_hz: float  # how far the frequency moves between a fit band and one twice as wide
    per_tap_hz: tuple[float, ...]

    @property
    def expanded_uncertainty_hz(self) -> float:
        """U = k u, k = 2."""
        return COVERAGE_K * self.u_hz


@dataclass(frozen=True, eq=False)
class TapResult:
    """The modes of a tap recording and its first hoop mode."""

    modes: tuple[TapMode, ...]
    tap_times_s: tuple[float, ...]
    window_s: float
    sample_rate_hz: float
    noise: float
    snr_db: float
    source: str
    warnings: tuple[str, ...] = ()
    spectrum: tuple[np.ndarray, np.ndarray] = field(default=(np.zeros(0), np.zeros(0)), repr=False)

    @property
    def hoop(self) -> TapMode:
        """The first hoop mode (analyze_tap refuses a recording without one)."""
        return next(m for m in self.modes if m.kind == "hoop")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        hoop = self.hoop
        modes = []
        for m in self.modes:
            d = asdict(m)
            d["per_tap_hz"] = list(m.per_tap_hz)
            d["expanded_uncertainty_hz"] = m.expanded_uncertainty_hz
            modes.append(d)
        return {
            "source": self.source,
            "hoop_hz": hoop.frequency_hz,
            "hoop_u_hz": hoop.u_hz,
            "hoop_expanded_uncertainty_hz": hoop.expanded_uncertainty_hz,
            "coverage_k": COVERAGE_K,
            "method": "output-only: taps' free decays, one pole per mode fitted to all taps",
            "modes": modes,
            "n_taps": len(self.tap_times_s),
            "tap_times_s": list(self.tap_times_s),
            "window_s": self.window_s,
            "resolution_hz": 1.0 / self.window_s,
            "sample_rate_hz": self.sample_rate_hz,
            "noise_floor": self.noise,
            "snr_db": self.snr_db,
            "warnings": list(self.warnings),
        }


def _check_silent(x: np.ndarray, where: str) -> None:
    """TooQuiet for a recording with no signal at all: a handful of sample values (silence, a constant,
    a bit of dither) is not a clipped tap, and no tap rings in it."""
    if np.unique(x[:SILENT_SCAN]).size > SILENT_LEVELS:  # the usual case, decided on the first samples
        return
    levels = np.unique(x).size
    if levels <= SILENT_LEVELS:
        raise TooQuiet(
            f"{where}silent: {levels} distinct sample value(s), no tap recorded: check the"
            f" microphone, its input and its gain"
        )


def _check_clipped(x: np.ndarray, where: str) -> None:
    peak = float(np.max(np.abs(x)))
    at = np.abs(x) >= peak * (1.0 - 1e-3)
    full = int(np.count_nonzero(np.abs(x) >= FULL_SCALE))
    if full >= 2 or longest_run(at) >= 3 or (np.count_nonzero(at) >= 4 and runs(at) >= 2):
        raise ClippedSignal(
            f"{where}clipped: {max(full, int(np.count_nonzero(at)))} samples at the recording's extreme"
            f" ({peak:.3g} of full scale): record again with less gain or the microphone further away"
        )


def _blocks(x: np.ndarray, n: int) -> np.ndarray:
    m = x.size // n
    return x[: m * n].reshape(m, n)


def _noise_floor(x: np.ndarray, fs: float) -> float:
    """The noise floor's RMS: the lesser of the quiet blocks' level and the unpredictable part."""
    nn = max(round(NOISE_BLOCK_S * fs), 1)
    quiet = float(np.percentile(np.sqrt(np.mean(_blocks(x, nn) ** 2, axis=1)), 10))
    p = min(PREDICTOR_ORDER, x.size // 8)
    r = fft.irfft(np.abs(fft.rfft(x, 2 * x.size)) ** 2)[: p + 1]  # autocorrelation, by FFT
    if p < 2 or r[0] <= 0.0:
        return max(quiet, np.finfo(float).tiny)
    r[0] *= 1.0 + 1e-9  # a ridge: a pure tone's Toeplitz matrix is singular
    try:
        a = linalg.solve_toeplitz(r[:p], r[1 : p + 1])  # Yule-Walker: x[n] ~ sum a_k x[n - k]
    except (linalg.LinAlgError, ValueError):
        return max(quiet, np.finfo(float).tiny)
    e = signal.lfilter(np.concatenate(([1.0], -a)), [1.0], x)[p:]
    unpredictable = MAD_TO_SIGMA * float(np.median(np.abs(e - np.median(e))))
    if not math.isfinite(unpredictable):
        unpredictable = quiet
    return max(min(quiet, unpredictable), np.finfo(float).tiny)


def _onsets(x: np.ndarray, fs: float, noise: float) -> tuple[list[int], int]:
    """Tap onsets (sample indices) and how many were dropped as bounces."""
    nb = max(round(BLOCK_S * fs), 1)
    env = np.max(np.abs(_blocks(x, nb)), axis=1)
    threshold = max(30.0 * noise, 0.05 * float(env.max()))
    back = max(round(LOOKBACK_S / BLOCK_S), 1)
    onsets: list[int] = []
    dropped = 0
    for i in (int(j) for j in np.flatnonzero(env >= threshold)):
        before = float(env[max(i - back, 0) : i].max(initial=0.0))
        if env[i] < ONSET_RISE * before:
            continue
        seg = np.abs(x[max(i - 1, 0) * nb : (i + 1) * nb])
        start = max(i - 1, 0) * nb + int(np.argmax(seg >= 0.2 * env[i]))
        if onsets and start - onsets[-1] < MIN_SPACING_S * fs:
            dropped += 1
            continue
        onsets.append(start)
    return onsets, dropped


def _windows(onsets: list[int], n: int, fs: float, where: str) -> tuple[list[int], int, list[str]]:
    """Window starts and the common length N; refuses too few taps or too short windows."""
    skip = round(SKIP_S * fs)
    starts = [o + skip for o in onsets]
    gaps = [b - a - skip for a, b in itertools.pairwise(starts)]
    length = min([*gaps, round(MAX_WINDOW_S * fs)])
    notes = []
    if starts and n - starts[-1] < length:
        if n - starts[-1] < length // 2 and len(starts) > MIN_TAPS:
            starts.pop()
            notes.append("the last tap, too close to the end of the recording, is left out")
        else:
            length = min(length, n - starts[-1])
    if len(starts) < MIN_TAPS:
        raise RecordTooShort(
            f"{where}{len(starts)} tap(s) found; tap the barrel at least {MIN_TAPS} times,"
            f" {MIN_WINDOW_S * 1e3:.0f} ms or more apart"
        )
    if length < MIN_WINDOW_S * fs:
        raise RecordTooShort(
            f"{where}the taps leave {length / fs * 1e3:.0f} ms of ring each (at least"
            f" {MIN_WINDOW_S * 1e3:.0f} ms needed for a {1 / MIN_WINDOW_S:.0f} Hz resolution)"
        )
    return starts, length, notes


def _damped_below_hoop(modes: list[TapMode], hoop_min_hz: float) -> list[str]:
    """Warnings for modes above `hoop_min_hz` and below the hoop found that the rule (rig.modal.output_only,
    assumed) called bending though they ring within NEAR_RULE times its damping limit: if the handle
    was held firmly the hoop rings damped too (and a damped peak is lower), and one may be the hoop."""
    hoop = next((m for m in modes if m.kind == "hoop"), None)
    if hoop is None:
        return []
    return [
        f"a mode at {m.frequency_hz:.0f} Hz lies above {hoop_min_hz:.0f} Hz and below the hoop found at"
        f" {hoop.frequency_hz:.0f} Hz: taken as bending (damping {m.damping_ratio / hoop.damping_ratio:.1f}"
        f" times the hoop's, peak {m.amplitude:.0%} of the loudest; the assumed rule wants at most"
        f" {DAMPING_FACTOR:g} times and {MIN_AMPLITUDE:.0%}); if the handle was held firmly it may be the"
        f" hoop: tap again with the bat hanging loosely"
        for m in modes
        if m.kind == "bending"
        and m.frequency_hz >= hoop_min_hz
        and m.damping_ratio <= NEAR_RULE * DAMPING_FACTOR * hoop.damping_ratio
    ]


def analyze_tap(wav: Wav, hoop_min_hz: float = HOOP_MIN_HZ) -> TapResult:
    """The first hoop frequency of a one-channel tap recording, with its uncertainty."""
    where = f"{wav.source}: " if wav.source else ""
    if wav.channels != 1:
        raise RecordingFormatError(
            f"{where}{wav.channels} channels: a tap recording has one (a two-channel impact test, force"
            f" and response, is read by `rig modal analyze`)"
        )
    x = wav.samples[:, 0] - float(np.median(wav.samples[:, 0]))
    fs = wav.rate_hz
    _check_silent(wav.samples[:, 0], where)
    _check_clipped(wav.samples[:, 0], where)
    nn = max(round(NOISE_BLOCK_S * fs), 1)
    if x.size < 4 * nn:
        raise RecordTooShort(f"{where}{x.size / fs * 1e3:.0f} ms long: record a few seconds of taps")
    noise = _noise_floor(x, fs)
    peak = float(np.max(np.abs(x)))
    snr_db = 20.0 * math.log10(max(peak, np.finfo(float).tiny) / noise)
    if snr_db < MIN_SNR_DB:
        raise TooQuiet(
            f"{where}too quiet: the loudest tap is {snr_db:.0f} dB above the noise floor, at least"
            f" {MIN_SNR_DB:.0f} dB needed: tap harder, or record closer to the barrel in a quieter room"
        )
    onsets, bounced = _onsets(x, fs, noise)
    starts, n, notes = _windows(onsets, x.size, fs, where)
    if bounced:
        notes.append(f"{bounced} second onset(s) within {MIN_SPACING_S * 1e3:.0f} ms of a tap ignored")
    dt = 1.0 / fs
    tau = n * dt / math.log(1.0 / EXP_END)
    w = np.exp(-np.arange(n) * dt / tau)
    spectra = fft.rfft(np.stack([x[a : a + n] * w for a in starts]), axis=-1)
    freq = fft.rfftfreq(n, dt)
    ones = np.ones((len(starts), freq.size))
    est = FrfEstimate(freq, spectra, ones, ones[0], spectra[:, None, :], dt, n, tau)
    band = (max(3.0 / (n * dt), 20.0), 0.45 * fs)
    peaks = find_mode_peaks(est, band, 0.5, PEAK_DECADES)
    floor = noise * math.sqrt(float(np.sum(w * w)))  # a white floor's |X| per tap
    peaks = [p for p in peaks if p.rise >= 5.0 * floor * math.sqrt(len(starts))]
    fitted = []
    for i, p in enumerate(peaks):
        bins = fit_band(est, peaks, i)
        joint = fit_mode(est, p, bins)
        # a room's reverberation bends a peak away from one pole's shape: how far the frequency moves
        # when the fit takes twice the band is u_model (0 for a clean free decay)
        half = (bins[1] - bins[0]) // 2
        wide = fit_mode(est, p, (max(1, bins[0] - half), min(freq.size, bins[1] + half)))
        u_model = abs(wide.frequency_hz - joint.frequency_hz) if wide.method == "pole fit" else 0.0
        per_tap = tuple(fit_mode(est, p, bins, np.stack([s, s])).frequency_hz for s in spectra)
        fitted.append((p, joint, per_tap, u_model))
    loudest = max(
        (float(math.sqrt(np.sum(np.abs(spectra[:, p.index]) ** 2))) for p, *_ in fitted), default=1.0
    )
    freqs = [j.frequency_hz for _, j, *_ in fitted]
    amps = [float(math.sqrt(np.sum(np.abs(spectra[:, p.index]) ** 2))) / loudest for p, *_ in fitted]
    kinds = output_only_kinds(freqs, [j.damping_ratio for _, j, *_ in fitted], amps, hoop_min_hz)
    modes = []
    df = 1.0 / (n * dt)
    for (_, joint, per_tap, u_model), kind, amp in zip(fitted, kinds, amps, strict=True):
        u_res = (RESOLUTION_SHARE if joint.method == "pole fit" else 1.0) * df / math.sqrt(12.0)
        u_spread = float(np.std(per_tap, ddof=1) / math.sqrt(len(per_tap)))
        u_room = ROOM_SHARE * 2.0 * joint.damping_ratio * joint.frequency_hz
        u = math.sqrt(u_res**2 + joint.u_frequency_hz**2 + u_spread**2 + u_model**2 + u_room**2)
        modes.append(
            TapMode(
                joint.frequency_hz,
                joint.damping_ratio,
                kind,
                amp,
                u,
                joint.u_frequency_hz,
                u_spread,
                u_model,
                per_tap,
            )
        )
    notes.extend(_damped_below_hoop(modes, hoop_min_hz))
    if not any(m.kind == "hoop" for m in modes):
        listed = ", ".join(f"{m.frequency_hz:.0f} Hz (damping {m.damping_ratio:.4f})" for m in modes)
        raise NoHoopMode(
            f"{where}no hoop mode: no lightly damped, strong mode above {hoop_min_hz:.0f} Hz;"
            f" modes: {listed or 'none'}"
        )
    power = np.sum(np.abs(spectra) ** 2, axis=0)
    return TapResult(
        modes=tuple(modes),
        tap_times_s=tuple(a / fs for a in onsets[: len(starts)]),
        window_s=n * dt,
        sample_rate_hz=fs,
        noise=noise,
        snr_db=snr_db,
        source=wav.source,
        warnings=tuple(notes),
        spectrum=(freq, power),
    )
