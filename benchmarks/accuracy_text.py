"""The sentences of docs/accuracy.md: each one computed from a study's numbers, none hard-coded."""

from __future__ import annotations

from collections.abc import Sequence

from rig.physics.fast import DEFAULT_RTOL
from studies.accuracy.curve_cost import CurveTradeoffRow
from studies.accuracy.first_step import FirstStepRow
from studies.accuracy.plots import case_label, format_time
from studies.accuracy.precision import (
    IMPLICIT,
    KERNEL,
    PrecisionRow,
    PrecisionStudy,
    cost_to_reach,
)

DECADES = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
TARGETS = (1e-4, 1e-6, 1e-8, 1e-10)


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
