"""Plots of the population study: the founding paper's Fig. 5 and Fig. 6 with the model overlaid."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from rig.population.dataset import METRICS
from rig.report.cert_plots import axis_label
from rig.report.model_plots import figure_paths
from studies.population.study import PopulationStudy

MATERIAL_STYLE = {"aluminium": ("C0", "o"), "composite": ("C3", "s"), "wood": ("C5", "^")}


def _save(fig: plt.Figure, path: Path) -> list[Path]:
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)
    return paths


def _tag(study: PopulationStudy) -> str:
    return " — SYNTHETIC sample data" if study.synthetic else ""


def plot_hoop_vs_bending(study: PopulationStudy, path: str | Path) -> list[Path]:
    """Fig. 5: first hoop frequency against first bending frequency, by barrel material."""
    fig, ax = plt.subplots(figsize=(7, 4.6), constrained_layout=True)
    for material in sorted({b.barrel.value for b in study.bats}):
        pts = [(b.bending_hz, b.hoop_hz) for b in study.bats if b.barrel.value == material and b.bending_hz]
        if not pts:
            continue
        color, marker = MATERIAL_STYLE.get(material, ("0.4", "x"))
        ax.scatter(
            [p[0] for p in pts], [p[1] for p in pts], c=color, marker=marker, label=f"{material} ({len(pts)})"
        )
    ax.set_xlabel("first bending frequency (Hz)")
    ax.set_ylabel("first hoop frequency (Hz)")
    ax.set_title("First hoop vs first bending frequency" + _tag(study), fontsize=10)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend()
    else:  # e.g. a store's simulated bats: no modal test, so no bending frequency
        ax.text(0.5, 0.5, "no bat has a first bending frequency", transform=ax.transAxes, ha="center")
    return _save(fig, Path(path))


def plot_metrics_vs_hoop(study: PopulationStudy, path: str | Path) -> list[Path]:
    """Fig. 6: each metric against hoop frequency, 50 Hz bins averaged over +-25 Hz, model overlaid."""
    fig, axes = plt.subplots(3, 1, figsize=(7, 9), sharex=True, constrained_layout=True)
    for ax, name in zip(axes, METRICS, strict=True):
        pts = [(b.hoop_hz, b.metric(name)) for b in study.bats if b.metric(name) is not None]
        ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=10, color="0.75", label="bats")
        bins = study.bins.get(name, [])
        if bins:
            ax.errorbar(
                [b.center_hz for b in bins],
                [b.mean for b in bins],
                yerr=[b.std or 0.0 for b in bins],
                fmt="o",
                color="C0",
                ms=5,
                capsize=2,
                label="average over ±25 Hz, every 50 Hz",
            )
        if study.model.get(name):
            ax.plot(
                study.model["hoop_hz"],
                study.model[name],
                color="C3",
                lw=1.5,
                label="model, paper's constants: mean over the bats' own MOI and length",
            )
        cal = study.calibrated
        if cal is not None and cal.get(name):
            offset = "" if name == cal["metric"] else " (no offset)" if "offset" in cal["parameters"] else ""
            ax.plot(
                cal["hoop_hz"],
                cal[name],
                color="C2",
                lw=1.8,
                ls="--",
                label=f"calibrated model ({cal['variant']}, {cal['provenance']['n_bats']} bats){offset}",
            )
        ax.set_ylabel(axis_label(name))
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[0].set_title("Performance vs hoop frequency" + _tag(study), fontsize=10)
    axes[-1].set_xlabel("first hoop frequency (Hz)")
    return _save(fig, Path(path))


def plot_population(study: PopulationStudy, directory: str | Path) -> list[Path]:
    """Both figures into `directory` (PNG and SVG each)."""
    d = Path(directory)
    return plot_hoop_vs_bending(study, d / "fig5-hoop-vs-bending.png") + plot_metrics_vs_hoop(
        study, d / "fig6-metrics-vs-hoop.png"
    )
