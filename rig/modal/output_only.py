"""Telling the first hoop mode from bending modes with one response only (no second accelerometer).

With two accelerometers 90 degrees apart the hoop mode is where their FRFs overlay (analysis.py).
With one microphone or one accelerometer that test is gone; what is left is where a mode lies and
how long it rings:
- position: a bat's first hoop mode lies above HOOP_MIN_HZ (the paper's bats: 1400-3000 Hz; the
  first three free-free bending modes lie below about 1000 Hz) [assumed bound];
- strength: a candidate must reach MIN_AMPLITUDE of the strongest mode above HOOP_MIN_HZ (a ping
  is dominated by its hoop tone, Russell 2017);
- damping: a hand or a floor holding the handle damps the bending modes, which move the whole bat,
  far more than the hoop mode, which rings in the barrel's shell (the ping) [assumed: no published
  damping ratios of held bats were found]. A strong mode counts as a hoop candidate when its damping
  ratio is at most DAMPING_FACTOR times the least damping of the strong modes. (A weak mode's
  damping is not used: in a room its late decay is the room's reverberation, which rings longer.)
The first hoop mode is the lowest candidate; modes below it are bending, modes above it are
unclassified (higher hoop or bending modes).
"""

from __future__ import annotations

from collections.abc import Sequence

HOOP_MIN_HZ = 1000.0  # [assumed] lowest first hoop frequency of a bat
DAMPING_FACTOR = 2.0  # [assumed] a hoop candidate rings at most this much more damped than the least
MIN_AMPLITUDE = 0.5  # [assumed] a hoop candidate's amplitude against the strongest above HOOP_MIN_HZ


def output_only_kinds(
    freqs_hz: Sequence[float],
    dampings: Sequence[float],
    amplitudes: Sequence[float] | None = None,
    hoop_min_hz: float = HOOP_MIN_HZ,
) -> list[str]:
    """Each mode's kind ("hoop" for the first hoop mode, "bending", "unclassified") by the rule above."""
    n = len(freqs_hz)
    amps = list(amplitudes) if amplitudes is not None else [1.0] * n
    above = [i for i in range(n) if freqs_hz[i] >= hoop_min_hz]
    if not above:
        return ["bending"] * n
    loudest = max(amps[i] for i in above)
    strong = [i for i in above if amps[i] >= MIN_AMPLITUDE * loudest]
    least = min(dampings[i] for i in strong)
    candidates = [i for i in strong if dampings[i] <= DAMPING_FACTOR * least]
    if not candidates:  # the loudest mode is a damped one and the ringing ones are faint: no hoop
        return ["bending" if f < hoop_min_hz else "unclassified" for f in freqs_hz]
    f_hoop = min(freqs_hz[i] for i in candidates)
    return ["hoop" if f == f_hoop else "bending" if f < f_hoop else "unclassified" for f in freqs_hz]
