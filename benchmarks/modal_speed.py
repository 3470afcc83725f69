"""What a modal analysis costs against a plain scipy H1 estimate of the same recording.

Issue 26, item 2: `rig.modal.analyze` of 4 hits x 0.1 s within 10 times a plain scipy H1 of the
same data. For each of `bats` simulated recordings (the accuracy study's bats: first hoop
1400-2800 Hz, hoop damping 0.3-1.5 %, noise 0.003, the bat at rest before every hit) both are
timed in turn, `repeats` times each, interleaved so that both see the same load on the machine;
per recording the fastest of each, and the ratio of the two. The baseline, written with scipy
alone: H1 and coherence of both accelerometers from scipy.signal.csd over the hit blocks
(one segment per hit, the analysis's exponential window), i.e. what the analysis's own FRF step
gives, without the mode fits. Used by benchmarks/bench_modal.py (--speed prints this alone).
"""

from __future__ import annotations

import gc
import math
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy import signal

from rig.modal import ModalSettings, Recording, SimMode, SimSettings, analyze, bat_modes, simulate

TARGET = 10.0  # issue 26: the analysis within 10 times the plain H1
WINDOW_S = 0.1
HITS = 4
QUIET_S = 0.005  # quiet lead-in of each block before its hit
NOISE = 3e-3
BENDING_HZ = 175.0


def settled(hits: int, window_s: float, noise: float, seed: int, modes: tuple[SimMode, ...]) -> SimSettings:
    """A simulated test of one block per hit, each `window_s` long after a quiet lead-in: the bat at
    rest before every hit (the accuracy study's recordings)."""
    return SimSettings(
        hits=hits,
        hit_interval_s=window_s + QUIET_S,
        first_hit_s=QUIET_S,
        settle=True,
        noise=noise,
        seed=seed,
        modes=modes,
    )


def plain_h1(rec: Recording, block_s: float, exp_end: float) -> tuple[np.ndarray, np.ndarray]:
    """H1 (2, K) and coherence (2, K) of both accelerometers by scipy.signal alone."""
    n = round(block_s * rec.fs)
    w = signal.windows.exponential(n, center=0, tau=n / math.log(1.0 / exp_end), sym=False)

    def spectrum(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        # scipy takes the window's samples (the stubs list only names and tuples)
        out = signal.csd(a, b, fs=rec.fs, window=w, nperseg=n, noverlap=0, detrend="constant")  # type: ignore[call-overload]
        return np.asarray(out[1])

    p_ff = spectrum(rec.force, rec.force).real
    h, coh = [], []
    for x in (rec.accel1, rec.accel2):
        p_xx = spectrum(x, x).real
        p_fx = spectrum(rec.force, x)
        h.append(p_fx / p_ff)
        coh.append(np.abs(p_fx) ** 2 / (p_ff * p_xx))
    return np.array(h), np.array(coh)


def _fastest(calls: list[Callable[[], object]], repeats: int) -> tuple[list[float], list[float]]:
    """Each call's fastest of `repeats` runs by the wall clock and by the process's CPU time (which
    leaves out the time other processes held the CPU), the calls interleaved, the collector paused."""
    wall = [math.inf] * len(calls)
    cpu = [math.inf] * len(calls)
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(repeats):
            for i, call in enumerate(calls):
                t0, c0 = time.perf_counter(), time.process_time()
                call()
                wall[i] = min(wall[i], time.perf_counter() - t0)
                cpu[i] = min(cpu[i], time.process_time() - c0)
    finally:
        if enabled:
            gc.enable()
    return wall, cpu


@dataclass(frozen=True)
class Speed:
    """Per recording: the analysis's and the plain H1's fastest times, seconds, by the wall clock
    and by CPU time."""

    analysis_s: list[float]
    h1_s: list[float]
    analysis_cpu_s: list[float]
    h1_cpu_s: list[float]
    repeats: int

    @staticmethod
    def _ratios(a: list[float], b: list[float]) -> list[float]:
        return [x / y for x, y in zip(a, b, strict=True)]

    @property
    def ratios(self) -> list[float]:
        """Analysis time over plain H1 time, per recording (wall clock)."""
        return self._ratios(self.analysis_s, self.h1_s)

    @property
    def cpu_ratios(self) -> list[float]:
        """The same by CPU time."""
        return self._ratios(self.analysis_cpu_s, self.h1_cpu_s)

    def lines(self) -> list[str]:
        """Markdown: one summary line and a table."""
        r, rc = statistics.median(self.ratios), statistics.median(self.cpu_ratios)
        ms = [1e3 * t for t in self.analysis_s]
        return [
            f"Analysis of {HITS} hits x {WINDOW_S:g} s (the study's settings; {len(ms)} simulated bats, each"
            f" timed {self.repeats} times interleaved with the baseline, the fastest kept): median"
            f" {statistics.median(ms):.1f} ms against {1e3 * statistics.median(self.h1_s):.2f} ms for a plain"
            f" scipy H1 and coherence of the same recording, **{r:.1f} times** by the wall clock and"
            f" **{rc:.1f} times** by CPU time (issue 26's target: at most {TARGET:g} times; load average"
            f" {_load()}).",
            "",
            "| per recording | median | fastest | slowest |",
            "| --- | ---: | ---: | ---: |",
            _row("analysis (ms)", ms, ".1f"),
            _row("plain scipy H1 + coherence (ms)", [1e3 * t for t in self.h1_s], ".2f"),
            _row("ratio, wall clock", self.ratios, ".1f"),
            _row("ratio, CPU time", self.cpu_ratios, ".1f"),
        ]


def _load() -> str:
    try:
        return str([round(x, 2) for x in os.getloadavg()])
    except (OSError, AttributeError):
        return "n/a"


def _row(name: str, xs: list[float], fmt: str) -> str:
    return f"| {name} | {statistics.median(xs):{fmt}} | {min(xs):{fmt}} | {max(xs):{fmt}} |"


def measure(bats: int = 12, repeats: int = 9, seed0: int = 17) -> Speed:
    """Time the analysis and the plain H1 on `bats` simulated recordings."""
    rng = np.random.default_rng(seed0)
    modal = ModalSettings(window_s=WINDOW_S, max_resolution_hz=1e3, min_spacing_s=WINDOW_S / 2)
    wall: list[list[float]] = []
    cpu: list[list[float]] = []
    for k in range(bats):
        hoop = float(rng.uniform(1400.0, 2800.0))
        damping = float(rng.uniform(0.003, 0.015))
        modes = bat_modes(hoop, BENDING_HZ, hoop_damping=damping)
        rec = simulate(settled(HITS, WINDOW_S, NOISE, seed0 * 1000 + k, modes))
        analyze(rec, modal)  # warm: imports and caches, as in a session that analyses bat after bat
        w, c = _fastest(
            [partial(analyze, rec, modal), partial(plain_h1, rec, WINDOW_S + QUIET_S, modal.exp_end)],
            repeats,
        )
        wall.append(w)
        cpu.append(c)
    return Speed(
        [w[0] for w in wall], [w[1] for w in wall], [c[0] for c in cpu], [c[1] for c in cpu], repeats
    )
