"""Signal checks and hit segmentation on the force channel.

- Noise floor: the force's median is its baseline and 1.4826 x the median absolute deviation
  its noise (robust: the pulses are a tiny fraction of the samples). The polarity is that of
  the largest excursion, so a force sensor wired the other way round works too.
- A pulse is a run of samples above threshold = max(threshold_sigma x noise, threshold_fraction
  x the largest pulse); runs closer than MERGE_S are one pulse (noise flicker at its edges).
- Every pulse must peak at least min_force_snr x the noise (else WeakHit: too noisy to trust).
- Hits: the first pulse opens a hit; a later pulse within the hit's window (or, with automatic
  windows, within min_spacing_s of the hit's first pulse) is a double hit; after it, a new hit.
- Window: from pretrigger_s before the first threshold crossing, of one length for every hit
  (given, or the shortest distance to the next hit's window or the end of the record).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.modal.errors import ClippedSignal, DoubleHit, FlatChannel, NoHits, RecordTooShort, WeakHit
from rig.modal.recording import CHANNELS, Recording

MERGE_S = 1e-4
CLIP_RUN = 3  # consecutive samples stuck at an extreme
CLIP_COUNT = 4  # ... or this many samples at it, in two places or more


@dataclass(frozen=True)
class Pulse:
    """One force pulse: sample indices of its first and last sample above threshold, and its peak."""

    start: int
    end: int
    peak_index: int
    peak_n: float


@dataclass(frozen=True)
class Hits:
    """The hits of a recording and the windows the FRF estimate uses."""

    starts: tuple[int, ...]  # first sample of each hit's window
    pulses: tuple[Pulse, ...]  # the pulse of each hit
    window_n: int  # samples per window (the same for every hit)
    baseline_n: float
    noise_n: float
    threshold_n: float
    polarity: float
    dropped: tuple[str, ...] = ()  # hits left out, with the reason
    accel_noise: tuple[float, float] | None = None  # noise std of each accelerometer
    noise_source: str | None = None  # "before the first hit", "tail", or None (not measurable)

    @property
    def count(self) -> int:
        """Number of hits used."""
        return len(self.starts)


def longest_run(mask: np.ndarray) -> int:
    """Length of the longest run of True in a boolean array."""
    if not mask.any():
        return 0
    padded = np.concatenate(([0], mask.astype(np.int8), [0]))
    edges = np.flatnonzero(np.diff(padded))
    return int(np.max(edges[1::2] - edges[::2]))


def runs(mask: np.ndarray) -> int:
    """Number of separate runs of True in a boolean array."""
    return int(np.count_nonzero(np.diff(np.concatenate(([0], mask.astype(np.int8)))) == 1))


def check_channels(rec: Recording, clip_run: int = CLIP_RUN) -> None:
    """Refuse a dead channel or one with flat tops at its extremes (saturation): a run of `clip_run`
    samples at an extreme, or CLIP_COUNT samples at it in two places or more (short runs)."""
    for name in CHANNELS:
        x = rec.channel(name)
        lo, hi = float(x.min()), float(x.max())
        span = hi - lo
        if span <= 1e-12 * max(abs(lo), abs(hi), 1.0):
            raise FlatChannel(
                f"{rec.source or 'recording'}: {name} is constant ({hi:g}): sensor dead or not connected"
            )
        centre = float(np.median(x))
        reach = max(hi - centre, centre - lo)
        tol = 1e-7 * span
        for label, extreme, stuck in (("top", hi, x >= hi - tol), ("bottom", lo, x <= lo + tol)):
            if abs(extreme - centre) < 0.5 * reach:
                continue  # the baseline side of a one-sided signal, not an extreme
            run = longest_run(stuck)
            count, places = int(np.count_nonzero(stuck)), runs(stuck)
            where = int(np.flatnonzero(stuck)[0])
            fix = "lower the gain or the hammer force and record again"
            if run >= clip_run:
                raise ClippedSignal(
                    f"{rec.source or 'recording'}: {name} is clipped: {run} consecutive samples stuck at its"
                    f" {label} value {extreme:.6g} (first at {rec.time_s[where]:.6g} s); {fix}"
                )
            if count >= CLIP_COUNT and places >= 2:
                # a ringing bat passes its largest value once; sitting on it again and again, if only
                # for a sample or two each time (a fast mode, a slow sample rate), is saturation
                raise ClippedSignal(
                    f"{rec.source or 'recording'}: {name} is clipped: {count} samples in {places} places"
                    f" stuck at its {label} value {extreme:.6g} (runs of up to {run}; first at"
                    f" {rec.time_s[where]:.6g} s); {fix}"
                )


def find_pulses(
    force: np.ndarray, fs: float, threshold_sigma: float, threshold_fraction: float
) -> tuple[list[Pulse], float, float, float, float]:
    """Pulses above the threshold; also the baseline, noise, threshold and polarity."""
    baseline = float(np.median(force))
    dev = force - baseline
    noise = 1.4826 * float(np.median(np.abs(dev)))
    polarity = 1.0 if dev.max() >= -dev.min() else -1.0
    signal = polarity * dev
    peak = float(signal.max())
    threshold = max(threshold_sigma * noise, threshold_fraction * peak)
    above = signal > threshold
    if not above.any():
        return [], baseline, noise, threshold, polarity
    padded = np.concatenate(([0], above.astype(np.int8), [0]))
    edges = np.flatnonzero(np.diff(padded))
    runs = [[int(a), int(b) - 1] for a, b in zip(edges[::2], edges[1::2], strict=True)]
    gap = max(3, round(MERGE_S * fs))
    merged = [runs[0]]
    for a, b in runs[1:]:
        if a - merged[-1][1] <= gap:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    pulses = []
    for a, b in merged:
        k = a + int(np.argmax(signal[a : b + 1]))
        pulses.append(Pulse(a, b, k, float(signal[k])))
    return pulses, baseline, noise, threshold, polarity


QUIET_MIN = 32  # samples before the first hit needed to measure the accelerometers' noise
TAIL_SHARE = 0.25  # else the noise comes from the last quarter of the last hit's window


def pulse_guard(fs: float) -> int:
    """Samples kept clear before a pulse's threshold crossing: its foot (and the response) rose earlier."""
    return max(3, round(2e-4 * fs))


def quiet_noise(rec: Recording, first: Pulse) -> tuple[float, float] | None:
    """Robust std of each accelerometer before the first pulse (None: too few quiet samples)."""
    end = first.start - pulse_guard(rec.fs)
    if end < QUIET_MIN:
        return None
    out = []
    for x in (rec.accel1[:end], rec.accel2[:end]):
        out.append(1.4826 * float(np.median(np.abs(x - np.median(x)))))
    return out[0], out[1]


def tail_noise(rec: Recording, start: int, window_n: int) -> tuple[float, float] | None:
    """Noise std of each accelerometer from the decayed tail of a hit's window (None: too short).

    The bat may still ring there (a bending mode decays slowly), so the level is not the tail's
    std but its spectrum's floor: under a Blackman-Harris window (sidelobes 92 dB down) a few modes
    leave most bins to the noise, and for white noise of std sigma each bin's power is exponential
    with median ln(2) sigma^2 sum(w^2).
    """
    from scipy.signal.windows import blackmanharris

    m = max(QUIET_MIN, int(TAIL_SHARE * window_n))
    end = min(start + window_n, rec.n)
    if end - m < start or m < QUIET_MIN:
        return None
    w = blackmanharris(m)
    t = np.arange(m, dtype=float)
    out = []
    for x in (rec.accel1[end - m : end], rec.accel2[end - m : end]):
        y = x - np.polyval(np.polyfit(t, x, 1), t)
        power = np.abs(np.fft.rfft(y * w)[1:-1]) ** 2
        out.append(float(np.sqrt(np.median(power) / (np.log(2.0) * np.sum(w * w)))))
    return out[0], out[1]


def segment(
    rec: Recording,
    *,
    threshold_sigma: float,
    threshold_fraction: float,
    pretrigger_s: float,
    window_s: float | None,
    min_spacing_s: float,
    min_force_snr: float = 20.0,
) -> Hits:
    """Find the hits and their common window; refuse no hits, double hits and no room."""
    fs = rec.fs
    pulses, baseline, noise, threshold, polarity = find_pulses(
        rec.force, fs, threshold_sigma, threshold_fraction
    )
    name = rec.source or "recording"
    if not pulses:
        raise NoHits(f"{name}: no hammer pulse above {threshold:.3g} N (noise floor {noise:.3g} N)")
    weak = [p for p in pulses if p.peak_n < min_force_snr * noise]
    if weak:
        p = weak[0]
        raise WeakHit(
            f"{name}: the hit at {rec.time_s[p.start]:.4f} s peaks at {p.peak_n:.3g} N, only"
            f" {p.peak_n / noise:.1f} x the force channel's noise ({noise:.3g} N;"
            f" {min_force_snr:g} x needed):"
            f" strike harder or find the noise"
        )
    pre = round(pretrigger_s * fs)
    fixed = None if window_s is None else round(window_s * fs)
    reach = fixed if fixed is not None else round(min_spacing_s * fs)
    hits: list[Pulse] = []
    for p in pulses:
        if hits and p.start - hits[-1].start < reach:
            first = hits[-1]
            gap = (p.start - first.start) / fs
            if fixed is not None and gap >= min_spacing_s and p.peak_n >= 0.5 * first.peak_n:
                # as strong as a hit and too late for a bounce: the window asked for is longer than
                # the hits' spacing (a bounce is weaker: a test keeps one at 35 % a double hit)
                raise RecordTooShort(
                    f"{name}: the hit at {rec.time_s[p.start]:.4f} s comes {gap:.3g} s after the one at"
                    f" {rec.time_s[first.start]:.4f} s, inside the window of {window_s:g} s asked for:"
                    f" give a window shorter than the time between hits (or leave it automatic)"
                )
            raise DoubleHit(
                f"{name}: double hit: hit {len(hits)} at {rec.time_s[first.start]:.4f} s is followed"
                f" {(p.start - first.start) / fs * 1e3:.2f} ms later by a second force pulse (peak"
                f" {p.peak_n:.3g} N, {100 * p.peak_n / first.peak_n:.0f}% of the first); the hammer"
                f" bounced: strike again, cleanly"
            )
        hits.append(p)
    starts = [max(0, p.start - pre) for p in hits]
    dropped: list[str] = []
    if fixed is not None:
        window = fixed
        while starts and starts[-1] + window > rec.n:
            dropped.append(
                f"hit at {rec.time_s[hits[-1].start]:.4f} s: only {(rec.n - starts[-1]) / fs:.4g} s of"
                f" record after it, the window is {window / fs:.4g} s"
            )
            starts.pop()
            hits.pop()
        if not starts:
            raise RecordTooShort(
                f"{name}: no hit has a full {window_s:g} s window in the record ({dropped[-1]})"
            )
    else:
        room = [b - pre - a for a, b in zip(starts[:-1], [p.start for p in hits[1:]], strict=True)]
        room.append(rec.n - starts[-1])
        if len(room) > 1 and room[-1] < 0.5 * min(room[:-1]):
            # a last hit cut short by the end of the record would shorten every window: leave it out
            dropped.append(
                f"hit at {rec.time_s[hits[-1].start]:.4f} s: only {room[-1] / fs:.4g} s of record after it"
            )
            starts.pop()
            hits.pop()
            room.pop()
        window = min(room)
    accel_noise, source = quiet_noise(rec, hits[0]), "before the first hit"
    if accel_noise is None:
        accel_noise, source = tail_noise(rec, starts[-1], int(window)), "tail"
    return Hits(
        starts=tuple(starts),
        pulses=tuple(hits),
        window_n=int(window),
        baseline_n=baseline,
        noise_n=noise,
        threshold_n=threshold,
        polarity=polarity,
        dropped=tuple(dropped),
        accel_noise=accel_noise,
        noise_source=None if accel_noise is None else source,
    )
