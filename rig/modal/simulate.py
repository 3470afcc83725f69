"""A simulated modal test: a free-free bat as a sum of damped modes, struck by a hammer.

Each mode r is a single-degree-of-freedom oscillator m_r q'' + c_r q' + k_r q = F(t) driven by the
hammer; accelerometer i reads shape_i * q_r'' summed over the modes. The hammer pulse is a
half-sine, and the response to it is computed in closed form (no time stepping), so the samples
are exact samples of the continuous response. Bending modes show strongly on accelerometer 1 (in
line with the hammer) and weakly on accelerometer 2; hoop modes (ovaling of the barrel) show on
both with comparable magnitude and opposite sign (cos 2 theta at 0 and 90 degrees).
Faults for tests: noise, clipping of either channel, a double hit. By default each hit finds the
bat still ringing from the one before (hits hit_interval_s apart); with `settle` every hit finds it
at rest, as when the operator waits and the acquisition keeps one block per hit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from rig.core.errors import ParameterError
from rig.modal.recording import Recording

DEFAULT_FS = 51200.0


@dataclass(frozen=True)
class SimMode:
    """One mode: undamped natural frequency, damping ratio, modal mass and its two shape values."""

    frequency_hz: float
    damping_ratio: float
    mass_kg: float
    shape1: float  # at accelerometer 1 (the hammer sits here too)
    shape2: float  # at accelerometer 2
    kind: str  # "bending" or "hoop"

    def __post_init__(self) -> None:
        if not (self.frequency_hz > 0 and math.isfinite(self.frequency_hz)):
            raise ParameterError("frequency_hz", self.frequency_hz, "must be finite and > 0")
        if not 0.0 < self.damping_ratio < 1.0:
            raise ParameterError("damping_ratio", self.damping_ratio, "must be in (0, 1)")
        if not self.mass_kg > 0:
            raise ParameterError("mass_kg", self.mass_kg, "must be > 0")


def bat_modes(
    hoop_hz: float | tuple[float, ...] = 1800.0,
    bending_hz: float = 175.0,
    hoop_damping: float = 0.006,
    bending_damping: float = 0.005,
) -> tuple[SimMode, ...]:
    """Modes resembling the paper's bats: three bending modes from `bending_hz`, and the hoop modes.

    A single hoop frequency also gets a second hoop mode at 1.7 times it, as in the paper's Fig. 1.
    """
    hoops = (hoop_hz, 1.7 * hoop_hz) if isinstance(hoop_hz, int | float) else tuple(hoop_hz)
    bending = tuple(
        SimMode(bending_hz * ratio, bending_damping * (1 + 0.2 * i), 0.22, 1.0, s2, "bending")
        for i, (ratio, s2) in enumerate(((1.0, 0.08), (2.75, 0.06), (5.3, 0.05)))
    )
    hoop = tuple(
        SimMode(f, hoop_damping, 0.09 * (1 + 0.3 * i), 1.0, -0.9 if i % 2 == 0 else 0.85, "hoop")
        for i, f in enumerate(hoops)
    )
    return bending + hoop


@dataclass(frozen=True)
class SimSettings:
    """How the simulated test is run; the fault fields are off by default."""

    fs: float = DEFAULT_FS
    hits: int = 5
    hit_interval_s: float = 0.5  # time from one hit to the next = the record length per hit
    first_hit_s: float = 0.01
    pulse_s: float = 150e-6  # half-sine duration (a metal hammer tip)
    peak_force_n: float = 200.0
    force_jitter: float = 0.2  # hit-to-hit peak force varies by +- this fraction
    noise: float = 1e-3  # white noise std, as a fraction of each channel's peak
    clip_force: float | None = None  # force saturates at this fraction of its peak
    clip_accel: float | None = None  # accelerometer 1 saturates at this fraction of its peak
    double_hit: int | None = None  # this hit (0-based) gets a second pulse
    double_hit_delay_s: float = 0.003
    double_hit_fraction: float = 0.35
    settle: bool = False  # each hit finds the bat at rest: the record is one block of hit_interval_s per hit
    seed: int = 0
    modes: tuple[SimMode, ...] = field(default_factory=bat_modes)

    def __post_init__(self) -> None:
        for name in ("fs", "hit_interval_s", "pulse_s", "peak_force_n"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ParameterError(name, value, "must be finite and > 0")
        if self.hits < 1:
            raise ParameterError("hits", self.hits, "must be at least 1")
        if self.noise < 0:
            raise ParameterError("noise", self.noise, "must be >= 0")
        if not self.modes:
            raise ParameterError("modes", self.modes, "need at least one mode")

    @property
    def duration_s(self) -> float:
        """Length of the simulated record, s."""
        return self.first_hit_s + self.hits * self.hit_interval_s

    def but(self, **changes: object) -> SimSettings:
        """A copy with some fields changed."""
        return replace(self, **changes)  # type: ignore[arg-type]


def _pole(mode: SimMode) -> complex:
    wn = 2.0 * math.pi * mode.frequency_hz
    z = mode.damping_ratio
    return complex(-z * wn, wn * math.sqrt(1.0 - z * z))


def pulse_response(
    t: np.ndarray, t0: float, width: float, peak: float, mode: SimMode
) -> tuple[np.ndarray, np.ndarray]:
    """Force and the modal acceleration q'' of `mode` for a half-sine pulse at t0 (closed form).

    Displacement impulse response r e^{pt} + conj, r = 1/(m (p - conj p)); the convolution with
    F0 sin(W u), 0 <= u <= width, is integrated exactly; q'' = p^2 q_p + p r F + r F' (times 2 Re).
    """
    p = _pole(mode)
    r = 1.0 / (mode.mass_kg * (p - p.conjugate()))
    w = math.pi / width
    jw = 1j * w
    u = t - t0
    force = np.where((u >= 0) & (u <= width), peak * np.sin(w * np.clip(u, 0.0, width)), 0.0)
    acc = np.zeros_like(t)

    def xp(v: np.ndarray | float) -> np.ndarray:
        # r e^{pv} int_0^v F0 sin(W x) e^{-px} dx, without growing exponentials
        ep = np.exp(p * v)
        return r * peak / 2j * ((np.exp(jw * v) - ep) / (jw - p) - (np.exp(-jw * v) - ep) / (-jw - p))

    during = (u >= 0) & (u <= width)
    ud = u[during]
    acc[during] = 2.0 * np.real(
        p * p * xp(ud) + p * r * peak * np.sin(w * ud) + r * peak * w * np.cos(w * ud)
    )
    after = u > width
    acc[after] = 2.0 * np.real(p * p * xp(width) * np.exp(p * (u[after] - width)))
    return force, acc


def simulate(settings: SimSettings | None = None) -> Recording:
    """A recording of `settings.hits` hammer hits on the simulated bat."""
    s = settings or SimSettings()
    rng = np.random.default_rng(s.seed)
    n = round(s.duration_s * s.fs)
    t = np.arange(n) / s.fs
    pulses: list[tuple[float, float, float, int]] = []  # (t0, width, peak, last sample + 1)
    for k in range(s.hits):
        t0 = s.first_hit_s + k * s.hit_interval_s + rng.uniform(0, 1) / s.fs  # off the sample grid
        peak = s.peak_force_n * (1.0 + s.force_jitter * rng.uniform(-1, 1))
        width = s.pulse_s * (1.0 + 0.05 * rng.uniform(-1, 1))
        # with `settle` the operator waited for the bat to come to rest: the DAQ kept one block per hit
        end = min(n, round((k + 1) * s.hit_interval_s * s.fs)) if s.settle else n
        pulses.append((t0, width, peak, end))
        if s.double_hit == k:
            pulses.append((t0 + s.double_hit_delay_s, width, peak * s.double_hit_fraction, end))
    force = np.zeros(n)
    a1 = np.zeros(n)
    a2 = np.zeros(n)
    for t0, width, peak, end in pulses:
        i0 = max(0, math.floor(t0 * s.fs))
        seg = t[i0:end]
        for j, mode in enumerate(s.modes):
            f, q_acc = pulse_response(seg, t0, width, peak, mode)
            if j == 0:
                force[i0:end] += f
            a1[i0:end] += mode.shape1 * q_acc
            a2[i0:end] += mode.shape2 * q_acc
    channels = []
    for x in (force, a1, a2):
        scale = float(np.max(np.abs(x))) or 1.0
        channels.append(x + s.noise * scale * rng.standard_normal(n))
    force, a1, a2 = channels
    if s.clip_force is not None:
        force = np.minimum(force, s.clip_force * float(np.max(force)))
    if s.clip_accel is not None:
        level = s.clip_accel * float(np.max(np.abs(a1)))
        a1 = np.clip(a1, -level, level)
    return Recording.build(t, force, a1, a2, source="simulated modal test")


def true_frequencies(settings: SimSettings, kind: str) -> list[float]:
    """The natural frequencies of the simulated modes of one kind, ascending."""
    return sorted(m.frequency_hz for m in settings.modes if m.kind == kind)
