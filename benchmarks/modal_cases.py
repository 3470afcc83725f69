"""The hard cases of the modal accuracy study: recordings as labs export them, and their faults.

Each case makes many simulated recordings of random bats, passes each through what a lab's
software would do to it (rounding the time column in a CSV export, clipping an accelerometer, a
short lead-in, heavy noise, a low mode), and analyses it the way `rig modal analyze` does (through
the CSV reader where the case is about the file). Per case the table gives how many recordings
were answered and how many diagnosed (by error code), the hoop frequency's error against the
simulated truth, the stated U (k = 2) and how often it covers the error, and the warnings seen.
A fault case passes when it is diagnosed every time; an export case when it is answered with U
covering the error (or given a diagnosis the case allows) and without a warning it forbids.
Used by benchmarks/bench_modal.py.
"""

from __future__ import annotations

import statistics
import tempfile
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rig.modal import (
    ModalError,
    ModalResult,
    ModalSettings,
    Recording,
    SimSettings,
    analyze,
    bat_modes,
    read_csv,
    simulate,
    write_csv,
)

Transform = Callable[[Recording, Path], Recording]


@dataclass
class Case:
    """One hard case: how its recordings are made, changed and analysed, and what it expects."""

    name: str
    expect: str  # "answer" or a diagnosis code
    sim: Callable[[float, float, int], SimSettings]  # (hoop, damping, seed) -> settings
    transform: Transform | None = None
    settings: ModalSettings = field(default_factory=ModalSettings)
    allowed: tuple[
        str, ...
    ] = ()  # diagnoses that are right answers too (e.g. LOW_COHERENCE under heavy noise)
    must_not_warn: str = ""  # a warning kind (see _warning_kind) that would be false here


@dataclass
class CaseResult:
    """The outcome of one case over its recordings."""

    case: Case
    errors: list[float] = field(default_factory=list)
    u_expanded: list[float] = field(default_factory=list)
    diagnoses: Counter[str] = field(default_factory=Counter)
    warnings: Counter[str] = field(default_factory=Counter)
    missing: int = 0  # answered, but without the mode asked about

    @property
    def answered(self) -> int:
        return len(self.errors) + self.missing

    def coverage(self) -> float:
        pairs = zip(self.errors, self.u_expanded, strict=True)
        return sum(abs(e) <= u for e, u in pairs) / len(self.errors) if self.errors else float("nan")

    def met(self, bats: int) -> bool:
        """Diagnosed every time (a fault), or answered every time with U covering >= 95 %."""
        if self.case.expect != "answer":
            return self.diagnoses[self.case.expect] == bats
        if self.case.must_not_warn and self.warnings[self.case.must_not_warn]:
            return False
        allowed = sum(self.diagnoses[code] for code in self.case.allowed)
        return len(self.errors) + allowed == bats and (not self.errors or self.coverage() >= 0.95)


def _round_time(fmt: Callable[[float], str]) -> Transform:
    def change(rec: Recording, tmp: Path) -> Recording:
        path = write_csv(rec, tmp / "src.csv")
        lines = path.read_text().splitlines()
        out = [lines[0]] + [f"{fmt(float(t))},{rest}" for t, rest in (ln.split(",", 1) for ln in lines[1:])]
        path.write_text("\n".join(out) + "\n")
        return read_csv(path)

    return change


def _clip(channel: str, fraction: float) -> Transform:
    def change(rec: Recording, _tmp: Path) -> Recording:
        chans = {c: rec.channel(c) for c in ("force", "accel1", "accel2")}
        level = fraction * float(np.max(np.abs(chans[channel])))
        chans[channel] = np.clip(chans[channel], -level, level)
        return Recording.build(rec.time_s, chans["force"], chans["accel1"], chans["accel2"])

    return change


def _blocks(hits: int, block_s: float, noise: float = 3e-3, **more: object) -> Callable[..., SimSettings]:
    def make(hoop: float, damping: float, seed: int) -> SimSettings:
        base = SimSettings(
            hits=hits,
            hit_interval_s=block_s,
            first_hit_s=0.005,
            settle=True,
            noise=noise,
            seed=seed,
            modes=bat_modes(hoop, 175.0, hoop_damping=damping),
        )
        return base.but(**more)

    return make


def cases() -> list[Case]:
    """The hard cases of issue 13 beside a clean baseline."""
    std = _blocks(4, 0.2)
    return [
        Case("clean CSV (baseline), 4 hits of 0.2 s", "answer", std, _round_time(lambda t: f"{t:.10g}")),
        Case("time rounded to 7 significant digits", "answer", std, _round_time(lambda t: f"{t:.7g}")),
        Case("time as float32", "answer", std, _round_time(lambda t: repr(float(np.float32(t))))),
        Case("time to 6 decimals (1 us)", "answer", std, _round_time(lambda t: f"{t:.6f}")),
        Case("accelerometer 1 clipped at 60 %", "CLIPPED", std, _clip("accel1", 0.6)),
        Case(
            "accelerometer 2 clipped at 60 %, 25.6 kHz",
            "CLIPPED",
            _blocks(4, 0.2, fs=25600.0),
            _clip("accel2", 0.6),
        ),
        Case(
            "first hit 0.2 ms into the record (noise from the tail)",
            "answer",
            _blocks(4, 0.2, first_hit_s=2e-4),
        ),
        Case(
            "noise 3 % of the peak, 2 s between hits: no 'still rang'",
            "answer",
            _blocks(3, 2.0, noise=0.03),
            allowed=("LOW_COHERENCE",),
            must_not_warn="still rang",
        ),
    ]


def run_case(case: Case, bats: int, seed0: int) -> CaseResult:
    """Analyse `bats` recordings of random bats (hoop 1400-2800 Hz, damping 0.3-1.5 %)."""
    out = CaseResult(case)
    rng = np.random.default_rng(seed0)
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(bats):
            hoop, damping = float(rng.uniform(1400.0, 2800.0)), float(rng.uniform(0.003, 0.015))
            rec = simulate(case.sim(hoop, damping, seed0 * 1000 + k))
            try:
                if case.transform is not None:
                    rec = case.transform(rec, Path(tmp))
                res = analyze(rec, case.settings)
            except ModalError as exc:
                out.diagnoses[exc.code] += 1
                continue
            _score(out, res, hoop)
    return out


def _score(out: CaseResult, res: ModalResult, hoop: float) -> None:
    for w in res.warnings:
        out.warnings[_warning_kind(w)] += 1
    if res.hoop is None:
        out.missing += 1
        return
    out.errors.append(res.hoop.frequency_hz - hoop)
    out.u_expanded.append(res.hoop.expanded_uncertainty_hz)


def _warning_kind(text: str) -> str:
    for needle, kind in (
        ("still rang", "still rang"),
        ("not clear of the FRF's noise", "peaks below noise"),
        ("ignored as noise", "peaks ignored (coherence)"),
        ("low coherence", "low coherence"),
        ("no noise level", "no noise level"),
        ("no hoop mode", "no hoop mode"),
    ):
        if needle in text:
            return kind
    return text.split(":")[0][:40]


def table(results: list[CaseResult], bats: int) -> list[str]:
    """Markdown rows, one per case."""
    rows = [
        "| case | expected | answered | diagnosed | RMS error (Hz) | largest error (Hz) | median U (Hz, k=2) "
        "| U covers | warnings (recordings) | met |",
        "| --- | --- | ---: | --- | ---: | ---: | ---: | ---: | --- | --- |",
    ]
    for r in results:
        diag = ", ".join(f"{v} {k}" for k, v in sorted(r.diagnoses.items())) or "-"
        warn = ", ".join(f"{k} {v}" for k, v in sorted(r.warnings.items())) or "-"
        if r.errors:
            rms = f"{float(np.sqrt(np.mean(np.square(r.errors)))):.3g}"
            worst = f"{float(np.max(np.abs(r.errors))):.3g}"
            u_med = f"{statistics.median(r.u_expanded):.3g}"
            cover = f"{round(100 * r.coverage())}% of {len(r.errors)}"
        else:
            rms = worst = u_med = cover = "-"
        expected = "an answer" if r.case.expect == "answer" else f"diagnosis {r.case.expect}"
        if r.case.allowed:
            expected += " (or " + ", ".join(r.case.allowed) + ")"
        if r.case.must_not_warn:
            expected += f", no '{r.case.must_not_warn}'"
        rows.append(
            f"| {r.case.name} | {expected} | {r.answered} of {bats} | {diag} | {rms} | {worst} | {u_med} "
            f"| {cover} | {warn} | {'yes' if r.met(bats) else '**no**'} |"
        )
    return rows
