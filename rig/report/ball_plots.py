"""The ball fit's figure: measured CCOR and the fitted model against speed (the founding paper's Fig. 3)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from rig.physics.ball_law import BallLaw
from rig.report.model_plots import figure_paths


def plot_ccor_fit(law: BallLaw, speeds: np.ndarray, model: np.ndarray, path: str | Path) -> list[Path]:
    """Each point with its u_ccor (else the residual scatter) as an error bar, and the model curve."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    v = np.array([p["speed_m_s"] for p in law.points])
    c = np.array([p["ccor"] for p in law.points])
    given = all(p.get("u_ccor") is not None for p in law.points)
    u = np.array([p["u_ccor"] for p in law.points]) if given else np.full(v.size, law.scatter)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.errorbar(
        v, c, yerr=u, fmt="o", ms=4, capsize=2, alpha=0.8, color="C0",
        label="measured" + (" (+- u_ccor)" if given else f" (+- residual scatter {law.scatter:.4f})"),
    )  # fmt: skip
    fitted = ", ".join(f"{n} = {law.parameters[n]:.4g} +- {law.uncertainty[n]:.2g}" for n in law.parameters)
    ax.plot(speeds, model, lw=1.8, color="C3", label=f"model, {law.variant}: {fitted}")
    ax.set_xlabel("inbound speed (m/s)")
    ax.set_ylabel("CCOR")
    title = "Cylindrical COR: measured and the fitted ball law"
    ax.set_title(title + (f" (lot {law.lot})" if law.lot else ""))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)
    return paths
