"""What accuracy costs in time: modal analysis of simulated impact tests.

For each record length per hit (the analysis window T) and number of averaged hits n, many
simulated bats (random first hoop frequency 1400-2800 Hz and hoop damping, fixed noise) are
analysed; the table gives the hoop frequency's error (RMS and largest), the stated expanded
uncertainty U (k = 2) and how often it covers the error, the coherence at the hoop mode, what the
lab spends (n T of recording) and the analysis wall time. A second table varies the noise at one
setting, a third shows the noise-free error against the resolution 1/T. A last section times the
analysis against a plain scipy H1 of the same recordings (benchmarks/modal_speed.py, issue 26).
Every figure is measured in this run. Run:  python benchmarks/bench_modal.py [--quick] [--write-doc]
(--write-doc replaces the results section of docs/modal.md); --speed runs the timing alone.
"""

from __future__ import annotations

import argparse
import platform
import re
import statistics
import sys
import time
from collections import Counter
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import scipy

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks.modal_cases
from benchmarks.modal_cases import cases, run_case
from benchmarks.modal_cases import table as case_table
from benchmarks.modal_speed import measure as measure_speed
from benchmarks.modal_speed import settled
from rig.modal import (
    ModalError,
    ModalResult,
    ModalSettings,
    SimMode,
    SimSettings,
    analyze,
    bat_modes,
    simulate,
)
from rig.modal.analysis import RESOLUTION_SHARE

DOC = Path(__file__).resolve().parents[1] / "docs" / "modal.md"
BEGIN, END = "<!-- bench_modal:begin -->", "<!-- bench_modal:end -->"
NOISE = 3e-3
BENDING_HZ = 175.0  # bat_modes' first bending mode


class ErrorStats:
    """RMS and largest error of a cell's recordings (the cells keep `errors`)."""

    errors: list[float]

    @property
    def ok(self) -> int:
        return len(self.errors)

    def rms(self) -> float:
        return float(np.sqrt(np.mean(np.square(self.errors)))) if self.errors else float("nan")

    def worst(self) -> float:
        return float(np.max(np.abs(self.errors))) if self.errors else float("nan")


@dataclass
class Cell(ErrorStats):
    """The outcome of one (T, n, noise) setting over many bats."""

    window_s: float
    hits: int
    noise: float
    errors: list[float]
    u_expanded: list[float]
    coherence: list[float]
    seconds: list[float]
    diagnoses: Counter[str]
    bending_errors: list[float]

    def coverage(self) -> float:
        pairs = zip(self.errors, self.u_expanded, strict=True)
        return sum(abs(e) <= u for e, u in pairs) / self.ok if self.ok else float("nan")


def timed_analysis(sim: SimSettings, modal: ModalSettings, cell: Cell | CloseCell) -> ModalResult | None:
    """Simulate, then analyse with the analysis alone timed into `cell.seconds`; None (the
    diagnosis counted in `cell.diagnoses`) where the analysis refuses the recording."""
    rec = simulate(sim)
    t0 = time.perf_counter()
    try:
        res = analyze(rec, modal)
    except ModalError as exc:
        cell.diagnoses[type(exc).__name__] += 1
        return None
    cell.seconds.append(time.perf_counter() - t0)
    return res


def run_cell(window_s: float, hits: int, noise: float, bats: int, seed0: int) -> Cell:
    """Analyse `bats` simulated recordings at this setting; the analysis alone is timed."""
    cell = Cell(window_s, hits, noise, [], [], [], [], Counter(), [])
    rng = np.random.default_rng(seed0)
    # the study's own settings: report what the analysis gives, even where the default refuses
    modal = ModalSettings(window_s=window_s, max_resolution_hz=1e3, min_spacing_s=window_s / 2)
    for k in range(bats):
        hoop = float(rng.uniform(1400.0, 2800.0))
        damping = float(rng.uniform(0.003, 0.015))
        modes = bat_modes(hoop, BENDING_HZ, hoop_damping=damping)
        res = timed_analysis(settled(hits, window_s, noise, seed0 * 1000 + k, modes), modal, cell)
        if res is None:
            continue
        if res.hoop is None:
            cell.diagnoses["no hoop mode"] += 1
            continue
        cell.errors.append(res.hoop.frequency_hz - hoop)
        cell.u_expanded.append(res.hoop.expanded_uncertainty_hz)
        cell.coherence.append(res.hoop.coherence)
        if res.bending_hz:
            cell.bending_errors.append(res.bending_hz[0] - BENDING_HZ)
    return cell


CLOSE_OFFSETS_HZ = (-50.0, -30.0, -20.0, 20.0, 30.0, 50.0)
CLOSE_WINDOWS_S = (0.2, 0.5, 2.0)
CLOSE_HITS = 3


@dataclass
class CloseCell(ErrorStats):
    """Hoop frequency with a bending mode `offset_hz` from it, one record length, many bats."""

    offset_hz: float
    window_s: float
    errors: list[float]
    u_expanded: list[float]
    seconds: list[float]
    neighbour_found: int  # the neighbour reported as its own bending mode
    warned: int  # a warning names the hoop as too close to a neighbour to separate
    diagnoses: Counter[str]

    def covered(self) -> int:
        return sum(abs(e) <= u for e, u in zip(self.errors, self.u_expanded, strict=True))


def close_mode_cell(offset_hz: float, window_s: float, bats: int, seed0: int) -> CloseCell:
    """Analyse `bats` simulated bats whose hoop mode has a bending mode `offset_hz` away."""
    cell = CloseCell(offset_hz, window_s, [], [], [], 0, 0, Counter())
    rng = np.random.default_rng(seed0)
    modal = ModalSettings(window_s=window_s, min_spacing_s=window_s / 2)
    for k in range(bats):
        hoop = float(rng.uniform(1400.0, 2800.0))
        damping = float(rng.uniform(0.003, 0.015))
        neighbour = SimMode(hoop + offset_hz, 0.006, 0.22, 1.0, 0.08, "bending")
        modes = (*bat_modes(hoop, BENDING_HZ, hoop_damping=damping), neighbour)
        res = timed_analysis(settled(CLOSE_HITS, window_s, NOISE, seed0 * 1000 + k, modes), modal, cell)
        if res is None:
            continue
        if any("too close" in w or "close modes" in w for w in res.warnings):
            cell.warned += 1
        if res.hoop is None:
            cell.diagnoses["no hoop mode"] += 1
            continue
        cell.errors.append(res.hoop.frequency_hz - hoop)
        cell.u_expanded.append(res.hoop.expanded_uncertainty_hz)
        near = abs(offset_hz) / 4
        if any(
            m.kind == "bending" and abs(m.frequency_hz - neighbour.frequency_hz) < near for m in res.modes
        ):
            cell.neighbour_found += 1
    return cell


def close_mode_cells(bats: int, quick: bool = False) -> list[CloseCell]:
    """Every (record length, neighbour offset) cell of the close-mode study."""
    windows = (0.2, 2.0) if quick else CLOSE_WINDOWS_S
    offsets = (-30.0, 20.0) if quick else CLOSE_OFFSETS_HZ
    pairs = [(w, o) for w in windows for o in offsets]
    return [close_mode_cell(o, w, bats, 700 + i) for i, (w, o) in enumerate(pairs)]


def close_summary(cells: list[CloseCell]) -> list[str]:
    """One paragraph: coverage over every close-mode recording, the neighbour found, the cost."""
    total = sum(c.ok for c in cells)
    covered = sum(c.covered() for c in cells)
    found = sum(c.neighbour_found for c in cells)
    worst = max(cells, key=lambda c: c.worst())
    seconds = [s for c in cells for s in c.seconds]
    offsets = ", ".join(f"{o:+g}" for o in sorted({c.offset_hz for c in cells}))
    return [
        f"A bending mode (damping 0.006, on accelerometer 1 mainly) {offsets}"
        f" Hz from the hoop mode, whose own damping is 0.003-0.015 (its half-power bandwidth 8-84 Hz):"
        f" the stated U (k=2) covered the hoop frequency's error in {covered} of {total} recordings"
        f" ({100 * covered / total:.1f}%), the neighbour was reported as its own bending mode in {found}"
        f" of {total}; the largest error, {worst.worst():.2g} Hz, came at T = {worst.window_s:g} s with the"
        f" neighbour {worst.offset_hz:+g} Hz away. Analysis {fmt_ms(seconds)} ms (median)."
    ]


def close_table(cells: list[CloseCell]) -> list[str]:
    rows = [
        "| neighbour (Hz from hoop) | T per hit (s) | RMS error (Hz) | largest error (Hz) "
        "| median U (Hz, k=2) | U covers | neighbour found | warned too close | analysis (ms, median) "
        "| diagnosed |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for c in cells:
        diag = ", ".join(f"{v} {k}" for k, v in sorted(c.diagnoses.items())) or "-"
        u_med = statistics.median(c.u_expanded) if c.ok else float("nan")
        rows.append(
            f"| {c.offset_hz:+g} | {c.window_s:g} | {c.rms():.3g} | {c.worst():.3g} | {u_med:.3g} "
            f"| {c.covered()} of {c.ok} | {c.neighbour_found} of {c.ok} | {c.warned} "
            f"| {fmt_ms(c.seconds)} | {diag} |"
        )
    return rows


def fmt_ms(seconds: list[float]) -> str:
    return f"{1e3 * statistics.median(seconds):.0f}" if seconds else "-"


def main_table(cells: list[Cell], default_max_df: float) -> list[str]:
    rows = [
        "| T per hit (s) | 1/T (Hz) | hits n | recording n·T (s) | RMS error (Hz) | largest error (Hz) "
        "| median U (Hz, k=2) | U covers | coherence at hoop (min) | first bending: RMS error (Hz), found "
        "| analysis (ms, median) | diagnosed |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for c in cells:
        refused = " (refused by default)" if 1.0 / c.window_s > default_max_df else ""
        diag = ", ".join(f"{v} {k}" for k, v in sorted(c.diagnoses.items())) or "-"
        coh = (
            f"{min(c.coherence):.3f}"
            if c.coherence and c.hits > 1
            else ("1 (one hit)" if c.coherence else "-")
        )
        u_med = statistics.median(c.u_expanded) if c.ok else float("nan")
        bend = "-"
        if c.bending_errors:
            bend = f"{np.sqrt(np.mean(np.square(c.bending_errors))):.2g}, {len(c.bending_errors)}/{c.ok}"
        rows.append(
            f"| {c.window_s:g}{refused} | {1 / c.window_s:.3g} | {c.hits} | {c.hits * c.window_s:.3g} "
            f"| {c.rms():.3g} | {c.worst():.3g} | {u_med:.3g} "
            f"| {c.ok and round(100 * c.coverage())}% of {c.ok} | {coh} | {bend} "
            f"| {fmt_ms(c.seconds)} | {diag} |"
        )
    return rows


def noise_table(cells: list[Cell]) -> list[str]:
    rows = [
        "| noise (fraction of peak) | RMS error (Hz) | largest error (Hz) | median U (Hz, k=2) | U covers "
        "| coherence at hoop (min) | diagnosed |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for c in cells:
        diag = ", ".join(f"{v} {k}" for k, v in sorted(c.diagnoses.items())) or "-"
        coh = f"{min(c.coherence):.3f}" if c.coherence else "-"
        rows.append(
            f"| {c.noise:g} | {c.rms():.3g} | {c.worst():.3g} "
            f"| {statistics.median(c.u_expanded) if c.ok else float('nan'):.3g} "
            f"| {c.ok and round(100 * c.coverage())}% of {c.ok} | {coh} | {diag} |"
        )
    return rows


def bias_table(cells: list[Cell]) -> list[str]:
    rows = [
        "| T (s) | 1/T (Hz) | largest noise-free error (Hz) | as a fraction of 1/T "
        f"| u_res = {RESOLUTION_SHARE:g}·(1/T)/√12 (Hz) |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for c in cells:
        df = 1.0 / c.window_s
        u_res = RESOLUTION_SHARE * df / 12**0.5
        rows.append(f"| {c.window_s:g} | {df:.3g} | {c.worst():.2g} | {c.worst() / df:.2g} | {u_res:.3g} |")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="fewer bats and settings (a smoke run)")
    parser.add_argument("--bats", type=int, default=12, help="simulated bats per setting")
    parser.add_argument("--write-doc", action="store_true", help="write the results into docs/modal.md")
    parser.add_argument("--speed", action="store_true", help="only time the analysis against a plain H1")
    args = parser.parse_args(argv)
    if args.speed:
        print("\n".join(measure_speed(bats=args.bats).lines()))
        return 0
    bats = 3 if args.quick else args.bats
    windows = (0.025, 0.1, 0.4) if args.quick else (0.025, 0.05, 0.1, 0.2, 0.4, 0.8)
    hit_counts = (1, 4) if args.quick else (1, 2, 4, 8)
    default_max_df = ModalSettings().max_resolution_hz
    started = time.perf_counter()
    load_before = _load()

    cells = [
        run_cell(w, n, NOISE, bats, 17 + i)
        for i, (w, n) in enumerate((w, n) for w in windows for n in hit_counts)
    ]
    noises = (0.0, 1e-3, 3e-3, 1e-2, 2e-2) if not args.quick else (0.0, 1e-2)
    noise_cells = [run_cell(0.2, 4, z, bats, 500 + i) for i, z in enumerate(noises)]
    bias_cells = [run_cell(w, 1, 0.0, bats, 900 + i) for i, w in enumerate(windows)]
    hard = [run_case(c, bats, 700) for c in cases()]  # the same bats in every case
    close_cells = close_mode_cells(bats, quick=args.quick)
    speed = measure_speed(bats=bats)
    took = time.perf_counter() - started

    by = {(c.window_s, c.hits): c for c in cells}
    lines: list[str] = []
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    lines.append(
        f"*Generated by `benchmarks/bench_modal.py` on {stamp}; {bats} simulated bats per setting, the"
        f" whole run took {took:.0f} s. Every number below comes from that run.*"
    )
    lines.append("")
    lines += _summary(by, windows, hit_counts, noise_cells, bias_cells, default_max_df)
    lines.append("")
    lines.append(f"#### Record length and hits (noise {NOISE:g} of each channel's peak)")
    lines.append("")
    lines += main_table(cells, default_max_df)
    lines.append("")
    lines.append("#### Noise (T = 0.2 s, 4 hits)")
    lines.append("")
    lines += noise_table(noise_cells)
    lines.append("")
    lines.append("#### Noise-free error against the resolution (one hit)")
    lines.append("")
    lines += bias_table(bias_cells)
    lines.append("")
    lines.append("#### Hard cases: exports and faults (the same bats in every case)")
    lines.append("")
    lines += case_table(hard, bats)
    lines.append("")
    lines.append(
        f"#### Close modes: a bending mode beside the hoop mode ({CLOSE_HITS} hits, noise {NOISE:g})"
    )
    lines.append("")
    lines += close_summary(close_cells)
    lines.append("")
    lines += close_table(close_cells)
    lines.append("")
    lines.append("#### Speed: the analysis against a plain scipy H1 of the same recording")
    lines.append("")
    lines += speed.lines()
    lines.append("")
    lines.append(
        f"Machine: Python {platform.python_version()}, NumPy {np.__version__}, SciPy {scipy.__version__};"
        f" {platform.platform()}; load average before {load_before}, after {_load()}."
    )
    text = "\n".join(lines)
    print(text)
    if args.write_doc:
        doc = DOC.read_text(encoding="utf-8")
        if BEGIN not in doc or END not in doc:
            print(f"{DOC}: no {BEGIN} ... {END} section to replace", file=sys.stderr)
            return 2
        new = re.sub(
            re.escape(BEGIN) + ".*?" + re.escape(END), lambda _: f"{BEGIN}\n{text}\n{END}", doc, flags=re.S
        )
        DOC.write_text(new, encoding="utf-8")
        print(f"wrote {DOC}", file=sys.stderr)
    return 0


def _summary(
    by: dict[tuple[float, int], Cell],
    windows: tuple[float, ...],
    hit_counts: tuple[int, ...],
    noise_cells: list[Cell],
    bias_cells: list[Cell],
    default_max_df: float,
) -> list[str]:
    out = ["### Summary", ""]
    longest, shortest = max(windows), min(windows)
    n_max, n_min = max(hit_counts), min(hit_counts)
    ref = by[(0.1, 4)] if (0.1, 4) in by else by[(windows[len(windows) // 2], n_max)]
    out.append(
        f"- At T = {ref.window_s:g} s per hit and {ref.hits} hits ({ref.hits * ref.window_s:.2g} s of"
        f" recording), the first hoop frequency is off by {ref.rms():.2g} Hz RMS (largest"
        f" {ref.worst():.2g} Hz) at noise"
        f" {NOISE:g}; the stated U (k=2) is {statistics.median(ref.u_expanded):.2g} Hz and covers"
        f" {round(100 * ref.coverage())}% of the errors. The analysis takes {fmt_ms(ref.seconds)} ms."
    )
    a, b = by[(shortest, n_max)], by[(longest, n_max)]
    out.append(
        f"- Record length: from T = {shortest:g} s to {longest:g} s ({n_max} hits) the RMS error goes from"
        f" {a.rms():.2g} Hz to {b.rms():.2g} Hz ({a.rms() / b.rms():.0f}x less) and U from"
        f" {statistics.median(a.u_expanded):.2g} to {statistics.median(b.u_expanded):.2g} Hz; the analysis"
        f" time from {fmt_ms(a.seconds)} to {fmt_ms(b.seconds)} ms."
    )
    c1, cn = by[(longest, n_min)], by[(longest, n_max)]
    out.append(
        f"- Hits: at T = {longest:g} s, {n_min} hit gives {c1.rms():.2g} Hz RMS, {n_max} hits"
        f" {cn.rms():.2g} Hz ({c1.rms() / cn.rms():.1f}x less, against sqrt({n_max}) = {n_max**0.5:.1f}"
        f" for pure noise);"
        f" one hit cannot check its coherence at all."
    )
    every = [c for c in [*by.values(), *noise_cells] if c.ok]
    covered = sum(round(c.coverage() * c.ok) for c in every)
    total = sum(c.ok for c in every)
    worst = min(every, key=lambda c: c.coverage())
    out.append(
        f"- The stated U (k=2) covered the error in {covered} of {total} recordings"
        f" ({100 * covered / total:.1f}%); the worst setting (T = {worst.window_s:g} s, {worst.hits} hit(s))"
        f" {round(100 * worst.coverage())}%. Where the resolution term dominates (short T) U is"
        f" generous; at long T it rests on the fit and the spread of the hits."
    )
    worst_bias = max(c.worst() * c.window_s for c in bias_cells)
    share = RESOLUTION_SHARE / 12**0.5
    out.append(
        f"- Without noise the fit's error stays below {worst_bias:.2g} of the resolution 1/T (third table),"
        f" inside the resolution term u_res = {RESOLUTION_SHARE:g}·(1/T)/√12 = {share:.3f}·(1/T)."
    )
    loud = noise_cells[-1]
    out.append(
        f"- Noise {loud.noise:g} of the peak still gives {loud.rms():.2g} Hz RMS with 4 hits of 0.2 s;"
        f" the default refuses windows shorter than {1 / default_max_df:.2g} s (1/T > {default_max_df:g} Hz)."
    )
    out.append(
        "- What to do in the lab: 3 to 5 hits with at least 0.1 s of record after each (more if the bat"
        " still rings; the analysis warns) resolve the hoop frequency to well under 1 Hz; the paper's"
        " 50 Hz bins need far less. Recording time, not computing time, is the cost."
    )
    return out


def _load() -> str:
    try:
        import os

        return str([round(x, 2) for x in os.getloadavg()])
    except (OSError, AttributeError):
        return "n/a"


if __name__ == "__main__":
    raise SystemExit(main())
