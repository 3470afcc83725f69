"""Plots of the collision model (matplotlib, no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from rig.physics.curve import EfficiencyCurve


def figure_paths(path: str | Path) -> list[Path]:
    """The files a plot goes to: the named one, plus its PNG/SVG twin."""
    target = Path(path)
    if target.suffix.lower() not in {".png", ".svg"}:
        target = target.with_suffix(".png")
    twin = target.with_suffix(".svg" if target.suffix.lower() == ".png" else ".png")
    return [target, twin]


def plot_efficiency_curve(curve: EfficiencyCurve, path: str | Path) -> list[Path]:
    """eta against hoop frequency with the optimum marked (the paper's Fig. 4)."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(curve.hoop_hz, curve.efficiency, lw=1.8, label=f"{curve.speed:g} m/s")
    ax.axhline(1.0, color="0.6", lw=0.8, ls="--", label="rigid barrel")
    ax.plot(
        [curve.optimum_hz],
        [curve.optimum_efficiency],
        "o",
        color="C3",
        label=f"optimum {curve.optimum_hz:.0f} Hz, eta = {curve.optimum_efficiency:.3f}",
    )
    ax.set_xlabel("hoop frequency (Hz)")
    ax.set_ylabel("normalized collision efficiency COR/COR_rigid")
    ax.set_title("Nonlinear mass-spring model: efficiency against hoop frequency")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)
    return paths
