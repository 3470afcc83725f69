"""docs/accuracy.md: run the work-precision study once and write its figures, tables and reading.

Every number in the written reading is computed from this run; the claims that could change with
the machine or library versions are phrased from the numbers, not hard-coded.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.fast import DEFAULT_RTOL
from rig.physics.params import DEFAULT_PARAMS
from rig.physics.precision import (
    EXPLICIT_RTOLS,
    IMPLICIT,
    IMPLICIT_RTOLS,
    KERNEL,
    MIN_TIMED_S,
    REFERENCE_AGREEMENT,
    REFERENCE_RTOL,
    CurveTradeoffRow,
    FirstStepRow,
    PrecisionRow,
    PrecisionStudy,
    ReferenceValue,
    ToleranceFit,
    cost_to_reach,
    curve_tradeoff,
    first_step_effect,
    load_average,
    work_precision,
)
from rig.report.precision_plots import (
    case_label,
    cost_markdown,
    curve_markdown_table,
    fits_markdown,
    format_time,
    markdown_table,
    plot_curve_tradeoff,
    plot_work_precision,
    references_markdown,
)

SPEED = 60.8
NEAR_RIGID_HZ = 1e6
DECADES = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
TARGETS = (1e-4, 1e-6, 1e-8, 1e-10)
NEAR_RIGID_RTOLS = tuple(10.0**-k for k in range(4, 11))
NEAR_RIGID_IMPLICIT_RTOLS = tuple(10.0**-k for k in range(4, 9))
NEAR_RIGID_REPEATS = 2  # its slowest solves take seconds

_PROBE = """
import json, statistics, sys, time
import numpy as np
from rig.physics import fast
from rig.physics.curve import cor_grid
from rig.physics.params import DEFAULT_PARAMS
fast.warm_up()
hoops = np.linspace(300.0, 20000.0, int(sys.argv[1]))
cor_grid(DEFAULT_PARAMS, 60.8, hoops, 1e-8)
ts = []
for _ in range(40):
    t0 = time.perf_counter(); cor_grid(DEFAULT_PARAMS, 60.8, hoops, 1e-8); ts.append(time.perf_counter() - t0)
print(json.dumps([min(ts), statistics.median(ts)]))
"""


def parallel_call_probe(points: int = 25) -> dict[str, list[float] | None]:
    """Min and median seconds of one cor_grid call in fresh processes, per OpenMP wait policy."""
    # numba's OpenMP layer (libgomp) lets idle workers spin and then sleep; how long waking them
    # takes depends on the policy and on other load. A fresh process per setting, since the policy
    # is read once when the runtime starts.
    out: dict[str, list[float] | None] = {}
    for name, extra in (("default", {}), ("OMP_WAIT_POLICY=passive", {"OMP_WAIT_POLICY": "passive"})):
        env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"} | extra
        try:
            done = subprocess.run(
                [sys.executable, "-c", _PROBE, str(points)],
                env=env,
                capture_output=True,
                text=True,
                timeout=120,
                check=True,
            )
            out[name] = json.loads(done.stdout.strip().splitlines()[-1])
        except (subprocess.SubprocessError, OSError, ValueError, IndexError):
            out[name] = None
    return out


def _cheapest(costs: dict[str, PrecisionRow | None], methods: Sequence[str]) -> PrecisionRow | None:
    found = [costs[m] for m in methods if costs.get(m) is not None]
    return min(found, key=lambda r: r.time_s) if found else None  # type: ignore[union-attr]


def _row(study: PrecisionStudy, method: str, rtol: float, hoop: float | None) -> PrecisionRow | None:
    for r in study.rows:
        if r.method == method and r.hoop_hz == hoop and abs(r.rtol / rtol - 1.0) < 1e-9:
            return r
    return None


def _at(r: PrecisionRow | None) -> str:
    return "—" if r is None else f"{format_time(r.time_s)} (rtol {r.rtol:.0e}, nfev {r.nfev})"


def _target_sentences(study: PrecisionStudy, targets: Sequence[float]) -> list[str]:
    """One line per case and target: the kernel's cost against the cheapest scipy method's."""
    scipy_methods = [m for m in study.methods() if m != KERNEL]
    lines = []
    for hoop in study.cases():
        for target in targets:
            costs = cost_to_reach(study, target, hoop)
            kern, best = costs.get(KERNEL), _cheapest(costs, scipy_methods)
            text = f"  - {case_label(hoop)}, |COR error| ≤ {target:.0e}: "
            if best is None:
                text += "no scipy method reached it reliably in the sweep"
            else:
                text += f"cheapest scipy method {best.method}, {_at(best)}"
            if kern is not None:
                text += f"; {KERNEL} {_at(kern)}"
                if best is not None:
                    text += f", {best.time_s / kern.time_s:.0f}× less time"
            else:
                text += f"; {KERNEL} did not reach it reliably"
            lines.append(text + ".")
    return lines


def _kernel_headline(study: PrecisionStudy) -> str:
    """Whether the kernel was the cheapest way to every target reached, and by what factor."""
    scipy_methods = [m for m in study.methods() if m != KERNEL]
    ratios, lost = [], []
    for hoop in study.cases():
        for target in TARGETS:
            costs = cost_to_reach(study, target, hoop)
            kern, best = costs.get(KERNEL), _cheapest(costs, scipy_methods)
            if kern is not None and best is not None:
                ratios.append(best.time_s / kern.time_s)
                if best.time_s < kern.time_s:
                    lost.append(f"{case_label(hoop)} ≤ {target:.0e}")
    head = f"- Use the compiled kernel ({KERNEL}, `rig.physics.fast.solve`)."
    if ratios and not lost:
        return (
            head + f" It was the cheapest way to every target both it and scipy reached, taking"
            f" {min(ratios):.0f}–{max(ratios):.0f}× less time than the cheapest scipy method:"
        )
    return head + f" Per target (scipy was cheaper for: {', '.join(lost) or 'none'}):"


def _implicit_wins(study: PrecisionStudy) -> list[str]:
    """Case and target pairs where an implicit method was the cheapest scipy choice."""
    scipy_methods = [m for m in study.methods() if m != KERNEL]
    wins = []
    for hoop in study.cases():
        for target in TARGETS:
            best = _cheapest(cost_to_reach(study, target, hoop), scipy_methods)
            if best is not None and best.method in IMPLICIT:
                wins.append(f"{case_label(hoop)} at ≤ {target:.0e}")
    return wins


def _stiff_sentence(study: PrecisionStudy, near: PrecisionStudy | None) -> list[str]:
    lines = []
    wins = _implicit_wins(study)
    cases = " and ".join(case_label(h) for h in study.cases())
    if wins:
        lines.append(f"- At {cases} an implicit method was the cheapest scipy choice for: {', '.join(wins)}.")
    else:
        r1 = _row(study, "Radau", 1e-8, study.cases()[0])
        r2 = _row(study, "DOP853", 1e-8, study.cases()[0])
        extra = ""
        if r1 is not None and r2 is not None:
            extra = (
                f" At rtol 1e-8 and {case_label(study.cases()[0])}, Radau took {format_time(r1.time_s)}"
                f" ({r1.nfev} nfev) against {format_time(r2.time_s)} ({r2.nfev} nfev) for DOP853."
            )
        lines.append(
            f"- At {cases} the problem is not stiff: Radau and BDF were never the cheapest way to any"
            f" target; they pay for a Jacobian and linear solves on every step.{extra}"
        )
    if near is None:
        return lines
    hoop = near.cases()[0]
    lines.append(
        f"- Near rigid ({case_label(hoop)}) the barrel's ringing makes the problem stiff; cheapest implicit"
        " method, cheapest other scipy method and the kernel, per target:"
    )
    for target in (1e-4, 1e-6, 1e-8):
        costs = cost_to_reach(near, target, hoop)
        exp = _cheapest(costs, [m for m in near.methods() if m not in IMPLICIT and m != KERNEL])
        imp = _cheapest(costs, [m for m in near.methods() if m in IMPLICIT])
        kern = costs.get(KERNEL)
        text = f"  - ≤ {target:.0e}: "
        text += f"best implicit {imp.method} {_at(imp)}" if imp else "no implicit method reached it"
        text += f"; best scipy explicit/LSODA {exp.method} {_at(exp)}" if exp else "; no scipy explicit"
        if imp is not None and exp is not None:
            text += f" ({imp.method} takes {imp.time_s / exp.time_s:.2g}× the time of {exp.method})"
        text += f"; {KERNEL} {_at(kern)}" if kern else f"; {KERNEL} not reliably"
        lines.append(text + ".")
    return lines


def _fit_sentence(study: PrecisionStudy) -> str:
    parts = []
    for m in study.methods():
        fits = [f for f in study.tolerance_fits if f.method == m]
        if fits:
            ps = ", ".join(f"{f.exponent:.2f}" for f in fits)
            sc = max(f.rms_log10_residual for f in fits)
            parts.append(f"{m} p = {ps} (scatter up to {sc:.2f} decades)")
    return "; ".join(parts)


def _nfev_span(study: PrecisionStudy, method: str) -> str:
    rows = sorted((r for r in study.rows if r.method == method), key=lambda r: -r.rtol)
    return f"{method}: " + ", ".join(f"{r.nfev} nfev at {r.rtol:.0e}" for r in rows)


def _contact_time_note(near: PrecisionStudy) -> list[str]:
    good = [r for r in near.rows if r.cor_error <= 1e-9]
    if not good:
        return []
    lo = min(r.contact_time_error for r in good)
    hi = max(r.contact_time_error for r in good)
    return [
        f"Contact time is far less well determined than COR here: the {len(good)} rows with |COR error|"
        f" ≤ 1e-9 have relative contact-time errors from {lo:.1e} to {hi:.1e}. A likely cause: the"
        " barrel's ringing ripples g near its zero, where the force, and so COR, hardly changes.",
        "",
    ]


def _first_step_table(rows: Sequence[FirstStepRow]) -> str:
    lines = [
        "| rtol | scipy first step | \\|COR err\\| (nfev), scipy default | same with the kernel's first step"
        f" | {KERNEL} |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        lines.append(
            f"| {r.rtol:.0e} | {r.scipy_first_step_s:.2g} s | {r.cor_error_default:.1e} ({r.nfev_default})"
            f" | {r.cor_error_kernel_step:.1e} ({r.nfev_kernel_step})"
            f" | {r.kernel_cor_error:.1e} ({r.kernel_nfev}) |"
        )
    return "\n".join(lines) + "\n"


def _env_lines(study: PrecisionStudy) -> list[str]:
    e = study.environment
    return [
        f"- Python {e.get('python')}, NumPy {e.get('numpy')}, SciPy {e.get('scipy')},"
        f" numba {e.get('numba')}.",
        f"- {e.get('platform')}; CPU {e.get('cpu')}, {e.get('cpu_count')} logical CPUs"
        f" ({e.get('cpus_usable', '?')} usable).",
        f"- Load average (1, 5, 15 min) before the study {e.get('load_average_before')},"
        f" after {e.get('load_average_after')}. The study itself adds about 1; more than that means"
        " other work shared the CPUs. Single-threaded timings suffer little from one competing process,"
        " parallel ones more.",
        f"- numba threading layer {e.get('numba_threading_layer')} with {e.get('numba_threads')} threads;"
        f" OMP_WAIT_POLICY {e.get('omp_wait_policy')}.",
    ]


def _curve_sentences(rows: Sequence[CurveTradeoffRow]) -> list[str]:
    lines = []
    for rtol in sorted({r.rtol for r in rows}, reverse=True):
        sel = [r for r in rows if r.rtol == rtol]
        cheap, dear = min(sel, key=lambda r: r.time_s), max(sel, key=lambda r: r.time_s)
        lines.append(
            f"  - rtol {rtol:.0e}: max |eta error| {min(r.max_eta_error for r in sel):.1e}"
            f"–{max(r.max_eta_error for r in sel):.1e} whatever the grid; whole curve"
            f" {format_time(cheap.time_s)} ({cheap.points} points) to {format_time(dear.time_s)}"
            f" ({dear.points} points)."
        )
    worst_grid = max(rows, key=lambda r: r.grid_optimum_error_hz)
    worst_opt = max(r.optimum_error_hz for r in rows)
    lines.append(
        f"  - The best grid point alone misses the optimum by up to {worst_grid.grid_optimum_error_hz:.0f} Hz"
        f" ({worst_grid.points} points); after the bounded-Brent refinement (at rtol 1e-12, whatever the"
        f" grid's rtol) every run agrees with the reference optimum to {worst_opt:.1e} Hz. Refinement"
        " locates the optimum to its xatol of 1e-3 Hz, so this is agreement of the procedure, not an"
        " accuracy finer than 1e-3 Hz."
    )
    return lines


def _scipy_sentence(study: PrecisionStudy) -> str:
    h0 = study.cases()[0]
    rows = [r for m in ("RK45", "DOP853", "LSODA") if (r := _row(study, m, 1e-10, h0)) is not None]
    if not rows:
        return "- (no scipy rows at rtol 1e-10)"
    cells = ", ".join(f"{r.method} {r.nfev} nfev / {format_time(r.time_s)} / {r.cor_error:.1e}" for r in rows)
    return (
        f"- Among scipy's methods at rtol 1e-10 and {case_label(h0)} (nfev / time / |COR error|): {cells}."
        + (
            " The fifth-order RK45 needs the most evaluations there."
            if max(rows, key=lambda r: r.nfev).method == "RK45"
            else ""
        )
    )


def _reading_lines(study: PrecisionStudy) -> list[str]:
    h0 = study.cases()[0]
    k10 = [r for h in study.cases() if (r := _row(study, KERNEL, DEFAULT_RTOL, h)) is not None]
    k_loose, k_tight = _row(study, KERNEL, 1e-4, h0), _row(study, KERNEL, 1e-12, h0)
    d10 = _row(study, "DOP853", 1e-10, h0)
    lines = [
        f"- **Which method.** For single solves and sweeps, {KERNEL}: at its default rtol"
        f" {DEFAULT_RTOL:g} it gave |COR error| "
        + ", ".join(f"{r.cor_error:.1e} in {format_time(r.time_s)} ({case_label(r.hoop_hz)})" for r in k10)
        + ". Use scipy only as the independent check, never in loops"
        + (f" (DOP853 at rtol 1e-10: {d10.cor_error:.1e} in {format_time(d10.time_s)})." if d10 else "."),
    ]
    if k_loose and k_tight:
        lines.append(
            f"- **Which tolerance.** With the kernel, going from rtol 1e-4 to 1e-12 raised the cost from"
            f" {format_time(k_loose.time_s)} to {format_time(k_tight.time_s)} and nfev from {k_loose.nfev} to"
            f" {k_tight.nfev} ({k_tight.nfev / k_loose.nfev:.1f}×) at {case_label(h0)}: eight decades of"
            " tolerance for a few times the work, as expected of an eighth-order method. Keep the default"
            f" rtol {DEFAULT_RTOL:g}; COR to ~1e-9 is far below what the rig measures (the light-gate COR"
            " uncertainty is about 1e-4, numerics.md §7)."
        )
    return lines


def _stiff_reading(study: PrecisionStudy, near: PrecisionStudy | None, rigid_gap: float | None) -> list[str]:
    if near is None:
        return ["- **Stiff methods** were not probed in this run (near_rigid=False)."]
    hoop = near.cases()[0]
    kernel_wins, implicit_beats_explicit = [], []
    for target in (1e-4, 1e-6, 1e-8):
        costs = cost_to_reach(near, target, hoop)
        best = _cheapest(costs, near.methods())
        if best is not None and best.method == KERNEL:
            kernel_wins.append(f"{target:.0e}")
        imp = _cheapest(costs, [m for m in near.methods() if m in IMPLICIT])
        exp = _cheapest(costs, [m for m in near.methods() if m not in IMPLICIT and m != KERNEL])
        if imp is not None and (exp is None or imp.time_s < exp.time_s):
            implicit_beats_explicit.append(f"{target:.0e}")
    text = (
        f"- **Stiff methods.** Near rigid ({case_label(hoop)}) an implicit method beat scipy's explicit ones"
    )
    text += (
        f" for target(s) {', '.join(implicit_beats_explicit)}"
        if implicit_beats_explicit
        else " for no target"
    )
    text += (
        f"; the compiled kernel was the cheapest of all for target(s) {', '.join(kernel_wins)}"
        if kernel_wins
        else "; the compiled kernel was not the cheapest for any target there"
    )
    paid = _implicit_wins(study)
    cases = " and ".join(case_label(h) for h in study.cases())
    text += (
        f". At {cases} an implicit method was the cheapest scipy choice for: {', '.join(paid)}."
        if paid
        else (f". At {cases} the implicit methods never paid off.")
    )
    if rigid_gap is not None:
        text += (
            f" For a truly stiff barrel use the rigid model: its COR differs from the"
            f" {case_label(hoop)} reference by {rigid_gap:.1e}, at the cost of one non-stiff 2-state solve."
        )
    return [text]


def build_markdown(
    study: PrecisionStudy,
    near: PrecisionStudy | None,
    curve: Sequence[CurveTradeoffRow],
    first_steps: Sequence[FirstStepRow],
    probe: dict[str, list[float] | None] | None,
    elapsed_s: float,
    figures: dict[str, str],
    rigid_gap: float | None = None,
    curve_load: Sequence[list[float] | None] = (),
    date: str = "",
) -> str:
    """The text of docs/accuracy.md from one run's results."""
    h0 = study.cases()[0]
    rk = _row(study, "RK45", 1e-6, h0)
    k5, k6, k7 = (_row(study, KERNEL, r, h0) for r in (1e-5, 1e-6, 1e-7))
    refs = study.references + (near.references if near else ())
    cor_lo, cor_hi = min(r.cor for r in refs), max(r.cor for r in refs)
    worst_ref = max(r.cor_disagreement for r in study.references + (near.references if near else ()))
    out: list[str] = [
        "# What accuracy costs in time: the collision solvers",
        "",
        f"*Generated by `benchmarks/accuracy_doc.py` on {date or 'an unrecorded date'};"
        f" the whole run took {elapsed_s:.0f} s"
        f" (the default study alone {study.elapsed_s:.1f} s). Every number below comes from that run.*",
        "",
        "The question: for one ball–barrel collision (60.8 m/s, clamped barrel), how much wall time and how"
        " many right-hand-side evaluations does each solver need for a given error in COR, and which"
        " solver should the controller use at which accuracy.",
        "",
        "## Summary",
        "",
        _kernel_headline(study),
        *_target_sentences(study, TARGETS),
        _scipy_sentence(study),
        *_stiff_sentence(study, near),
        f"- Tolerance is not error. Tolerance-proportionality fits of |COR error| = C·rtol^p:"
        f" {_fit_sentence(study)}.",
    ]
    if rk is not None:
        out.append(
            f"  - RK45 at rtol 1e-6 gave |COR error| {rk.cor_error:.1e}, {rk.cor_error / rk.rtol:.0f}× the"
            " tolerance."
        )
    if k5 and k6 and k7:
        out.append(
            f"  - {KERNEL} at rtol 1e-5, 1e-6, 1e-7: {k5.cor_error:.1e}, {k6.cor_error:.1e},"
            f" {k7.cor_error:.1e} — not monotone in the tolerance. Pick a tolerance from measured error"
            " with margin, never from the tolerance value."
        )
    out += [
        f"- The two reference methods (DOP853 and Radau at rtol {REFERENCE_RTOL:g}) agree on COR to"
        f" {worst_ref:.1e} in every case, far below the smallest error plotted.",
        "",
        "## How the study is done",
        "",
        "- **Problem.** The paper's model (`rig.physics.params.DEFAULT_PARAMS`), ball at"
        f" {SPEED:g} m/s on a clamped barrel, hoop frequencies"
        f" {', '.join(case_label(h) for h in study.cases())}"
        " (near the efficiency optimum and above it), plus a near-rigid probe at"
        f" {case_label(NEAR_RIGID_HZ)}. Contact ends where the contact force returns to zero (event on"
        " g = F/|d|^b).",
        f"- **Reference.** scipy `solve_ivp` DOP853 at rtol {REFERENCE_RTOL:g} (atol = rtol × scale per"
        " component), checked against Radau at the same tolerance, an implicit method with unrelated"
        f" error control. The study refuses to run (SolverError) if they disagree by more than"
        f" {REFERENCE_AGREEMENT:g}.",
        "",
        references_markdown(*([study, near] if near else [study])),
        "- **Error measure.** |COR − COR_ref| at the end of contact"
        f" (COR is {cor_lo:.2f}–{cor_hi:.2f} here, so this is nearly a relative error) and the relative"
        " error of the contact time. An end-point error, as in DETEST and the Hairer–Wanner test-set"
        " drivers.",
        "- **Cost.** nfev as reported by each solver (machine-independent), and wall time per solve:"
        " one warm-up solve (its result gives the errors), then the best of"
        f" {study.repeats} timed batches (`time.perf_counter`, garbage collector off). Solves faster than"
        f" {MIN_TIMED_S * 1e3:g} ms are timed in loops that last at least that long, divided by the count."
        f" The near-rigid probe uses {near.repeats if near else '-'} timed repeat(s).",
        f"- **Tolerances.** rtol from {max(EXPLICIT_RTOLS):.0e} to {min(EXPLICIT_RTOLS):.0e} in half decades"
        f" for {KERNEL}, RK45, DOP853 and LSODA; decades from {max(IMPLICIT_RTOLS):.0e} to"
        f" {min(IMPLICIT_RTOLS):.0e} for Radau and BDF, whose tight tolerances are slow. atol = rtol × (the"
        " compression scale for positions, v0 for velocities), the same for every method.",
        "- **Tolerance proportionality.** Per method and case, a least-squares line through"
        " log10(|COR error|) against log10(rtol) over the rows whose error is above the references'"
        " disagreement: error = C·rtol^p (DETEST, TOMS 648).",
        "- **Machine.**",
        *("  " + line for line in _env_lines(study)),
        "",
        "## Results: 60.8 m/s, clamped barrel",
        "",
        f"![work-precision]({figures['main']})",
        "",
        "### Time to reach a given |COR error|",
        "",
        "Each cell: the wall time per solve at the loosest tolerance from which on *every* tighter tolerance"
        " in the sweep also meets the target (a lucky loose tolerance does not count), and that tolerance.",
        "",
        cost_markdown(study, TARGETS),
        "### Rows at decade tolerances",
        "",
        "The half-decade rows are in the appendix and in `docs/accuracy.json`.",
        "",
        markdown_table(study, rtols=DECADES),
        "### Tolerance proportionality",
        "",
        "p = 1 means the error follows the tolerance; the rms residual says how erratically.",
        "",
        fits_markdown(study),
    ]
    if near is not None:
        out += [
            f"## Near-rigid barrel ({case_label(NEAR_RIGID_HZ)}): where stiff methods pay off",
            "",
            "The barrel rings with very little damping, so explicit methods are held to tiny steps by"
            f" stability, not accuracy ({_nfev_span(near, 'DOP853')}). Implicit methods step over the"
            " ringing at loose tolerance but must resolve it at tight tolerance"
            f" ({_nfev_span(near, 'Radau')}).",
            "",
            f"![work-precision near rigid]({figures['near']})",
            "",
            cost_markdown(near, (1e-4, 1e-6, 1e-8)),
            *_contact_time_note(near),
            markdown_table(near),
            fits_markdown(near),
        ]
    h_scipy = first_steps[0].scipy_first_step_s
    out += [
        "## Why the kernel beats scipy's DOP853 at loose tolerance",
        "",
        f"{KERNEL} is the same Dormand–Prince 8(5,3) method with the same error norm and step control."
        " The difference is the first step. The contact force grows like d^b with b ≈ 0.52 at impact"
        " (not Lipschitz), so the first steps' error estimates are unreliable and where the steps land"
        " decides much of the final error. solve_ivp's `select_initial_step` proposes a first step of"
        f" {h_scipy:.2g} s, {h_scipy / study.references[0].contact_time_s:.0%} of the whole contact, while"
        f" the kernel starts at 1e-4 × compression scale / v0 = {first_steps[0].kernel_first_step_s:.2g} s."
        " With `first_step` set to the kernel's, scipy reproduces the kernel's error and nfev"
        f" ({case_label(h0)}):",
        "",
        _first_step_table(first_steps),
        "A `first_step` argument in `rig.physics.reference.solve_reference` would make the scipy path"
        " markedly more accurate at loose tolerance for fewer evaluations.",
        "",
        "## The efficiency curve: grid density and tolerance",
        "",
        "`efficiency_curve` solves a grid of hoop frequencies in parallel lanes, then refines the optimum"
        " with bounded Brent at rtol 1e-12. Errors: max |eta − eta_ref| over the grid points against"
        f" `cor_grid` at rtol {REFERENCE_RTOL:g}, and the refined optimum against `efficiency_curve` on"
        " 2001 points at rtol 1e-12, refined. Times are best-of-N wall times on all CPUs"
        + (f"; load average before and after: {curve_load[0]}, {curve_load[-1]}." if curve_load else "."),
        "",
        f"![curve trade-off]({figures['curve']})",
        "",
        curve_markdown_table(curve),
        *_curve_sentences(curve),
        "",
    ]
    if probe:
        parts = [
            f"{name}: min {v[0] * 1e3:.2f} ms, median {v[1] * 1e3:.2f} ms" if v else f"{name}: probe failed"
            for name, v in probe.items()
        ]
        out += [
            "**Parallel calls and OpenMP.** While this study was being developed, with another process"
            " busy on this 2-CPU machine, every parallel call (even a trivial `prange` loop) took 6–8 ms"
            " under numba's OpenMP layer with the default wait policy, against about 0.05 ms with"
            " `OMP_WAIT_POLICY=passive`; a plain CPU-bound competitor did not always trigger it. Timings"
            " quantized at multiples of 8 ms are the symptom. `benchmarks/accuracy_doc.py` therefore sets"
            " OMP_WAIT_POLICY=passive unless it is set"
            f" (this run: {study.environment.get('omp_wait_policy')}). Fresh-process probe in this run,"
            f" one `cor_grid` call on 25 points at rtol 1e-8: {'; '.join(parts)}.",
            "",
        ]
    out += [
        "## Reading",
        "",
        *_reading_lines(study),
        *_stiff_reading(study, near, rigid_gap),
        "- **Tolerance is not error**: measure the error (this study) and choose the tolerance from it.",
        "- **Timing caveats.** Best-of-N on a shared virtual machine; compare methods within one run,"
        " not across machines; nfev is the portable measure.",
        "",
        "## Regenerating",
        "",
        "```sh",
        ".venv/bin/python benchmarks/accuracy_doc.py   # this page, its figures and docs/accuracy.json",
        "make accuracy                                 # the work-precision table and figure only",
        ".venv/bin/rig model accuracy --quick --json  # a smoke run",
        "```",
        "",
        "## Appendix: all rows",
        "",
        "<details><summary>Every tolerance of the default study</summary>",
        "",
        markdown_table(study),
        "</details>",
        "",
    ]
    return "\n".join(out)


def write_accuracy_doc(
    path: str | Path = "docs/accuracy.md",
    repeats: int = 5,
    near_rigid: bool = True,
    probe: bool = True,
) -> dict[str, Any]:
    """Run the study, write the doc, its figures (PNG and SVG) and raw JSON; returns what was written."""
    started = time.perf_counter()
    doc = Path(path)
    fig_dir = doc.parent / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    study = work_precision(repeats=repeats, speed=SPEED)
    near = None
    if near_rigid:
        near = work_precision(
            repeats=NEAR_RIGID_REPEATS,
            speed=SPEED,
            hoops=(NEAR_RIGID_HZ,),
            rtols=NEAR_RIGID_RTOLS,
            implicit_rtols=NEAR_RIGID_IMPLICIT_RTOLS,
        )
    curve_load = [load_average()]
    curve = curve_tradeoff(speed=SPEED, repeats=repeats)
    curve_load.append(load_average())
    h0 = study.cases()[0]
    first = first_step_effect(Impact(DEFAULT_PARAMS, SPEED, h0), cor_ref=study.references[0].cor)
    probed = parallel_call_probe() if probe else None
    rigid_gap = None
    if near is not None:
        rigid_gap = abs(fast.solve(Impact(DEFAULT_PARAMS, SPEED), rtol=1e-12).cor - near.references[0].cor)
    written, figures = _write_figures(study, near, curve, fig_dir)
    elapsed = time.perf_counter() - started
    date = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    raw = {
        "generated": date,
        "study": study.as_dict(),
        "near_rigid": near.as_dict() if near else None,
        "curve_tradeoff": [r.as_dict() for r in curve],
        "curve_tradeoff_load_average": curve_load,
        "first_step": [r.as_dict() for r in first],
        "parallel_call_probe": probed,
        "rigid_model_gap": rigid_gap,
        "elapsed_s": elapsed,
    }
    data_path = doc.with_suffix(".json")
    data_path.write_text(json.dumps(raw, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    doc.write_text(
        build_markdown(study, near, curve, first, probed, elapsed, figures, rigid_gap, curve_load, date),
        encoding="utf-8",
    )
    return {"doc": doc, "data": data_path, "figures": written, "elapsed_s": elapsed}


def _study_from_dict(d: dict[str, Any]) -> PrecisionStudy:
    return PrecisionStudy(
        rows=tuple(PrecisionRow(**r) for r in d["rows"]),
        references=tuple(ReferenceValue(**r) for r in d["references"]),
        tolerance_fits=tuple(ToleranceFit(**f) for f in d["tolerance_fits"]),
        environment=d["environment"],
        repeats=d["repeats"],
        elapsed_s=d["elapsed_s"],
    )


def rebuild_accuracy_doc(path: str | Path = "docs/accuracy.md") -> dict[str, Any]:
    """Rewrite the doc and its figures from the JSON a previous run saved beside it (no re-measuring)."""
    doc = Path(path)
    raw = json.loads(doc.with_suffix(".json").read_text(encoding="utf-8"))
    study = _study_from_dict(raw["study"])
    near = _study_from_dict(raw["near_rigid"]) if raw.get("near_rigid") else None
    curve = [CurveTradeoffRow(**r) for r in raw["curve_tradeoff"]]
    first = [FirstStepRow(**r) for r in raw["first_step"]]
    fig_dir = doc.parent / "figures"
    written, figures = _write_figures(study, near, curve, fig_dir)
    text = build_markdown(
        study,
        near,
        curve,
        first,
        raw.get("parallel_call_probe"),
        raw["elapsed_s"],
        figures,
        raw.get("rigid_model_gap"),
        raw.get("curve_tradeoff_load_average", ()),
        raw.get("generated", ""),
    )
    doc.write_text(text, encoding="utf-8")
    return {"doc": doc, "data": doc.with_suffix(".json"), "figures": written, "elapsed_s": raw["elapsed_s"]}


def _write_figures(
    study: PrecisionStudy, near: PrecisionStudy | None, curve: Sequence[CurveTradeoffRow], fig_dir: Path
) -> tuple[list[Path], dict[str, str]]:
    fig_dir.mkdir(parents=True, exist_ok=True)
    written = plot_work_precision(study, fig_dir / "work-precision.png")
    written += plot_curve_tradeoff(curve, fig_dir / "curve-tradeoff.png")
    figures = {"main": "figures/work-precision.png", "curve": "figures/curve-tradeoff.png"}
    if near is not None:
        written += plot_work_precision(near, fig_dir / "work-precision-near-rigid.png")
        figures["near"] = "figures/work-precision-near-rigid.png"
    return written, figures


__all__ = ["build_markdown", "parallel_call_probe", "rebuild_accuracy_doc", "write_accuracy_doc"]
