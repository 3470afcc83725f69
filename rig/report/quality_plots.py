"""The check standard's control charts as one figure: session means, their EWMA, the s-chart."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from rig.quality.charts import Charts
from rig.report.model_plots import figure_paths


def plot_charts(
    charts: Charts, title: str, path: str | Path, metric: str = "", unit: str = "check session"
) -> list[Path]:
    """Three panels: the individuals chart (warning, action limits), the EWMA (its exact limits) and
    the s-chart (B3, B4), phase I shaded, signals ringed; two when no point has a spread (one value
    per `unit`, as the model cross-check's residuals)."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    pts = charts.points
    x = [p.index for p in pts]
    with_s = [p for p in pts if p.s is not None]
    panels = 3 if with_s else 2
    fig, axes = plt.subplots(panels, 1, figsize=(8, 2.8 * panels), sharex=True)
    mean_ax, ewma_ax = axes[0], axes[1]
    s_ax = axes[2] if with_s else None
    mean_ax.plot(x, [p.mean for p in pts], "o-", ms=3, lw=1, color="C0", label=unit)
    limits = charts.limits()
    if limits is not None:
        for name, style in (("centre", "-"), ("warning", "--"), ("action", ":")):
            for side in ("low", "high") if name != "centre" else ("",):
                key = f"{name}_{side}" if side else name
                mean_ax.axhline(limits[key], ls=style, lw=1, color="C3" if name == "action" else "grey")
    two = [p for p in pts if p.phase == 2 and p.ewma is not None]
    if two:
        xs = [p.index for p in two]
        ewma_ax.plot(xs, [p.ewma for p in two], "o-", ms=3, lw=1, color="C1", label="EWMA")
        ewma_ax.plot(xs, [p.ewma_high for p in two], ":", color="C3", lw=1)
        ewma_ax.plot(xs, [p.ewma_low for p in two], ":", color="C3", lw=1)
        if charts.centre is not None:
            ewma_ax.axhline(charts.centre, lw=1, color="grey")
    if s_ax is not None:
        s_ax.plot([p.index for p in with_s], [p.s for p in with_s], "o-", ms=3, lw=1, color="C2", label="s")
    judged = [p for p in with_s if p.s_high is not None]
    if judged and s_ax is not None:
        s_ax.plot([p.index for p in judged], [p.s_high for p in judged], ":", color="C3", lw=1)
        s_ax.plot([p.index for p in judged], [p.s_centre for p in judged], "-", color="grey", lw=1)
    by_index = {p.index: p for p in pts}
    for sig in charts.signals:
        ax = {"action limit": mean_ax, "EWMA": ewma_ax, "s-chart": s_ax}[sig.rule]
        if ax is not None:
            ax.plot([by_index[sig.index].index], [sig.value], "o", ms=10, mfc="none", mec="C3")
    labels = (f"mean {metric}", "EWMA of the means", "s within a session") if with_s else (metric, "EWMA")
    for ax, label in zip(axes, labels[:panels], strict=True):
        if charts.phase_i:
            ax.axvspan(0.5, min(charts.phase_i, len(pts)) + 0.5, color="grey", alpha=0.08)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    phase = (
        "standard values given, no phase I"
        if charts.given
        else f"phase I: the first {charts.phase_i}, shaded"
    )
    axes[-1].set_xlabel(f"{unit} ({phase})")
    mean_ax.set_title(title)
    fig.tight_layout()
    for p in paths:
        fig.savefig(p, dpi=110)
    plt.close(fig)
    return paths
