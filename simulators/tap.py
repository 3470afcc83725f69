"""A tap on the simulated barrel: the ping a phone records when the barrel is tapped (one channel).

Each tap rings the barrel's modes as decaying sines (the hoop mode at the world's hoop frequency,
lightly damped; bending modes below it, damped by the hand holding the handle; a second hoop mode at
1.7 times the first), with a short contact click and white noise. The same shape as the pings the
tap analysis is tested on (tests/modal/test_tap.py), without the room. All values [assumed].
"""

from __future__ import annotations

import numpy as np

RATE_HZ = 48000
# (frequency as a share of the hoop's, or Hz for bending modes, damping ratio, amplitude)
BENDING = ((172.0, 0.03, 0.3), (478.0, 0.025, 0.4), (921.0, 0.02, 0.3))
HOOP = ((1.0, 0.003, 1.0), (1.7, 0.004, 0.4))


def ping(
    hoop_hz: float, seed: int, taps: int = 6, interval_s: float = 0.4, noise: float = 3e-4
) -> np.ndarray:
    """`taps` taps on a barrel whose first hoop mode is `hoop_hz`, sampled at RATE_HZ, peak 0.5."""
    rng = np.random.default_rng(seed)
    n = int((0.2 + taps * interval_s) * RATE_HZ)
    x = np.zeros(n)
    t = np.arange(int(interval_s * RATE_HZ)) / RATE_HZ
    modes = [*BENDING, *((share * hoop_hz, zeta, amp) for share, zeta, amp in HOOP)]
    for k in range(taps):
        start = int((0.1 + k * interval_s + rng.uniform(0, 0.02)) * RATE_HZ)
        ring = np.zeros(t.size)
        for f, zeta, amp in modes:
            wd = 2 * np.pi * f * np.sqrt(1 - zeta**2)
            ring += amp * rng.uniform(0.7, 1.3) * np.exp(-zeta * 2 * np.pi * f * t) * np.sin(wd * t)
        click = np.where(t < 3e-4, np.sin(np.pi * t / 3e-4), 0.0)
        seg = rng.uniform(0.6, 1.0) * (ring + 0.5 * click)
        m = min(seg.size, n - start)
        x[start : start + m] += seg[:m]
    x *= 0.5 / np.max(np.abs(x))
    return x + noise * 0.5 * rng.standard_normal(n)
