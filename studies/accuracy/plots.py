"""Work-precision plots and tables of the collision solvers (matplotlib Agg, rich, Markdown)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import NullFormatter
from rich.table import Table

from rig.report.model_plots import figure_paths
from studies.accuracy.curve_cost import CurveTradeoffRow
from studies.accuracy.precision import (
    PrecisionRow,
    PrecisionStudy,
    cost_to_reach,
)

ERROR_FLOOR = 1e-16  # exact agreement (error 0) is drawn here: log axes cannot show zero
_STYLE = {  # fixed per method, so that every figure reads the same
    "rig-DOP853": ("C3", "o"),
    "DOP853": ("C0", "s"),
    "RK45": ("C1", "^"),
    "LSODA": ("C2", "D"),
    "Radau": ("C4", "v"),
    "BDF": ("C5", "P"),
}


def case_label(hoop_hz: float | None) -> str:
    """A hoop case as text: '1250 Hz', '1 MHz' or 'rigid'."""
    if hoop_hz is None:
        return "rigid"
    return f"{hoop_hz / 1e6:g} MHz" if hoop_hz >= 1e6 else f"{hoop_hz:g} Hz"


def format_time(seconds: float) -> str:
    """Seconds in the unit that keeps 3 significant digits readable (us, ms or s)."""
    if seconds < 1e-3:
        return f"{seconds * 1e6:.3g} µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def _rows(study: PrecisionStudy, method: str, hoop: float | None) -> list[PrecisionRow]:
    return sorted((r for r in study.rows if r.method == method and r.hoop_hz == hoop), key=lambda r: -r.rtol)


def plot_work_precision(study: PrecisionStudy, path: str | Path) -> list[Path]:
    """|COR error| against time per solve and against nfev, one panel row per hoop case (PNG and SVG)."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    cases = study.cases()
    fig, axes = plt.subplots(len(cases), 2, figsize=(11, 4.2 * len(cases)), squeeze=False)
    floors = {ref.hoop_hz: ref.cor_disagreement for ref in study.references}
    for row_axes, hoop in zip(axes, cases, strict=True):
        for method in study.methods():
            rows = _rows(study, method, hoop)
            if not rows:
                continue
            color, marker = _STYLE.get(method, (None, "x"))
            err = [max(r.cor_error, ERROR_FLOOR) for r in rows]
            kw = dict(color=color, marker=marker, ms=4.5, lw=1.3, label=method)
            row_axes[0].loglog([r.time_s for r in rows], err, **kw)
            row_axes[1].loglog([r.nfev for r in rows], err, **kw)
        for ax, xlabel in zip(row_axes, ("wall time per solve (s)", "RHS evaluations (nfev)"), strict=True):
            if hoop in floors:
                ax.axhline(floors[hoop], color="0.5", lw=0.8, ls="--", label="DOP853 vs Radau reference")
            ax.set_xlabel(xlabel)
            ax.set_ylabel("|COR − COR_ref|")
            ax.set_title(f"{case_label(hoop)}, {study.rows[0].speed:g} m/s")
            ax.grid(alpha=0.3, which="both", lw=0.4)
    # One legend for the figure, below the panels, so that it never hides a curve.
    handles, labels = axes[0][1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 7), fontsize=8, frameon=False)
    fig.suptitle("Work-precision of the collision solvers (one marker per tolerance)")
    fig.tight_layout(rect=(0.0, 0.05 / len(cases), 1.0, 1.0))
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths


def plot_curve_tradeoff(rows: Sequence[CurveTradeoffRow], path: str | Path) -> list[Path]:
    """Efficiency curve: max |eta error| against wall time, and wall time against grid points (PNG, SVG)."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    fig, (ax_err, ax_time, ax_opt) = plt.subplots(1, 3, figsize=(15, 4.4))
    rtols = sorted({r.rtol for r in rows}, reverse=True)
    for k, rtol in enumerate(rtols):
        sel = sorted((r for r in rows if r.rtol == rtol), key=lambda r: r.points)
        color = f"C{k}"
        err = [max(r.max_eta_error, ERROR_FLOOR) for r in sel]
        ax_err.loglog([r.time_s for r in sel], err, "o-", color=color, label=f"rtol {rtol:g}")
        for r, e in zip(sel, err, strict=True):
            ax_err.annotate(
                str(r.points), (r.time_s, e), fontsize=7, xytext=(3, 3), textcoords="offset points"
            )
        pts = [r.points for r in sel]
        ax_time.loglog(pts, [r.time_s for r in sel], "o-", color=color, label=f"whole curve, rtol {rtol:g}")
        ax_time.loglog(pts, [r.grid_time_s for r in sel], "o--", color=color, alpha=0.6, label="grid only")
    by_points = {r.points: r for r in sorted(rows, key=lambda r: -r.rtol)}  # the optimum ignores rtol
    pts = sorted(by_points)
    ax_opt.loglog(
        pts, [by_points[n].grid_optimum_error_hz for n in pts], "s-", color="0.4", label="best grid point"
    )
    ax_opt.loglog(
        pts,
        [max(by_points[n].optimum_error_hz, ERROR_FLOOR) for n in pts],
        "o-",
        color="C3",
        label="refined (bounded Brent, xatol 1e-3 Hz)",
    )
    ax_opt.set_xlabel("grid points")
    ax_opt.set_ylabel("|optimum − reference optimum| (Hz)")
    ax_opt.set_title("where the optimum is")
    ax_err.set_xlabel("wall time of efficiency_curve (s)")
    ax_err.set_ylabel("max |eta − eta_ref| over the grid")
    ax_err.set_title("accuracy against cost (labels: grid points)")
    ax_time.set_xlabel("grid points")
    ax_time.set_ylabel("wall time (s)")
    ax_time.set_title("cost of the grid and of the refined optimum")
    for ax in (ax_err, ax_time, ax_opt):
        ax.grid(alpha=0.3, which="both", lw=0.4)
        ax.xaxis.set_minor_formatter(NullFormatter())  # crowded minor labels on short log ranges
        ax.legend(fontsize=8)
    fig.suptitle("Efficiency curve: grid density and tolerance against cost")
    fig.tight_layout()
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths


def precision_table(study: PrecisionStudy) -> Table:
    """The study's rows as a rich table for the terminal."""
    refs = "; ".join(
        f"{case_label(r.hoop_hz)}: COR_ref {r.cor:.12f} (Radau differs by {r.cor_disagreement:.1e})"
        for r in study.references
    )
    table = Table(title=f"Work-precision at {study.rows[0].speed:g} m/s — {refs}", show_header=True)
    for name in ("hoop", "method", "rtol", "|COR err|", "t_c rel err", "nfev", "time/solve"):
        table.add_column(name, justify="left" if name in {"hoop", "method"} else "right")
    for r in study.rows:
        table.add_row(
            case_label(r.hoop_hz),
            r.method,
            f"{r.rtol:.0e}",
            f"{r.cor_error:.2e}",
            f"{r.contact_time_error:.2e}",
            str(r.nfev),
            format_time(r.time_s),
        )
    return table


def _md(header: Sequence[str], body: Iterable[Sequence[str]], right_from: int = 1) -> str:
    align = ["---" if k < right_from else "---:" for k in range(len(header))]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(align) + " |"]
    lines += ["| " + " | ".join(cells) + " |" for cells in body]
    return "\n".join(lines) + "\n"


def markdown_table(study: PrecisionStudy, rtols: Iterable[float] | None = None) -> str:
    """The rows as a Markdown table, one column group per hoop case; `rtols` keeps only those tolerances."""
    keep = None if rtols is None else {float(f"{x:.3g}") for x in rtols}
    cases = study.cases()
    header = ["method", "rtol"]
    for hoop in cases:
        c = case_label(hoop)
        header += [f"{c}: \\|COR err\\|", f"{c}: t_c err", f"{c}: nfev", f"{c}: time"]
    body = []
    for method in study.methods():
        by_rtol: dict[float, dict[float | None, PrecisionRow]] = {}
        for r in study.rows:
            if r.method == method and (keep is None or float(f"{r.rtol:.3g}") in keep):
                by_rtol.setdefault(r.rtol, {})[r.hoop_hz] = r
        for rtol in sorted(by_rtol, reverse=True):
            cells = [method, f"{rtol:.0e}"]
            for hoop in cases:
                row = by_rtol[rtol].get(hoop)
                if row is None:
                    cells += ["—"] * 4
                else:
                    cells += [
                        f"{row.cor_error:.1e}",
                        f"{row.contact_time_error:.1e}",
                        str(row.nfev),
                        format_time(row.time_s),
                    ]
            body.append(cells)
    return _md(header, body, right_from=2)


def fits_markdown(study: PrecisionStudy) -> str:
    """The tolerance-proportionality fits cor_error = C rtol^p as a Markdown table."""
    body = [
        [
            f.method,
            case_label(f.hoop_hz),
            f"{f.exponent:.2f}",
            f"{f.constant:.2g}",
            str(f.points),
            f"{f.rms_log10_residual:.2f}",
        ]
        for f in study.tolerance_fits
    ]
    return _md(["method", "case", "p", "C", "points", "rms residual (decades)"], body, right_from=2)


def references_markdown(*studies: PrecisionStudy) -> str:
    """The references of each case (of one or more studies) and how far the two methods agree, as Markdown."""
    body = [
        [
            case_label(r.hoop_hz),
            f"{r.cor:.13f}",
            f"{r.cor_radau:.13f}",
            f"{r.cor_disagreement:.1e}",
            f"{r.contact_time_s * 1e3:.10f}",
            f"{r.contact_time_disagreement:.1e}",
        ]
        for study in studies
        for r in study.references
    ]
    header = ["case", "COR (DOP853)", "COR (Radau)", "\\|ΔCOR\\|", "t_c (ms, DOP853)", "t_c rel. diff."]
    return _md(header, body)


def cost_markdown(study: PrecisionStudy, targets: Sequence[float] = (1e-4, 1e-6, 1e-8, 1e-10)) -> str:
    """Per case and target |COR error|, each method's time (and rtol) to reach it reliably, as Markdown."""
    methods = study.methods()
    body = []
    for hoop in study.cases():
        for target in targets:
            best = cost_to_reach(study, target, hoop)
            cells = [case_label(hoop), f"≤ {target:.0e}"]
            for m in methods:
                r = best.get(m)
                cells.append("not reached" if r is None else f"{format_time(r.time_s)} ({r.rtol:.0e})")
            body.append(cells)
    return _md(["case", "target", *methods], body, right_from=2)


def curve_markdown_table(rows: Sequence[CurveTradeoffRow]) -> str:
    """The efficiency-curve trade-off as a Markdown table."""
    body = [
        [
            str(r.points),
            f"{r.rtol:.0e}",
            format_time(r.grid_time_s),
            format_time(r.time_s),
            f"{r.max_eta_error:.1e}",
            f"{r.grid_optimum_error_hz:.3g}",
            f"{r.optimum_error_hz:.1e}",
        ]
        for r in rows
    ]
    header = [
        "points",
        "rtol",
        "grid time",
        "whole curve time",
        "max \\|eta err\\|",
        "best grid point err (Hz)",
        "refined optimum err (Hz)",
    ]
    return _md(header, body, right_from=0)


__all__ = [
    "case_label",
    "cost_markdown",
    "curve_markdown_table",
    "fits_markdown",
    "format_time",
    "markdown_table",
    "plot_curve_tradeoff",
    "plot_work_precision",
    "precision_table",
    "references_markdown",
]
