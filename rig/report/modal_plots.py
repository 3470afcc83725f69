"""Plot of a modal analysis: both accelerometers' FRF magnitudes and coherence, modes marked."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from rig.modal.analysis import ModalResult
from rig.modal.tap import TapResult
from rig.report.model_plots import figure_paths

KIND_STYLE = {"hoop": ("C3", "hoop"), "bending": ("C0", "bending"), "unclassified": ("0.5", "unclassified")}


def plot_modal(result: ModalResult, path: str | Path) -> list[Path]:
    """|H1| and |H2| against frequency (log scale) over coherence, the identified modes marked."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    frf = result.frf
    lo, hi = result.band_hz
    sel = (frf.freq_hz >= lo) & (frf.freq_hz <= hi)
    f = frf.freq_hz[sel]
    fig, (ax, axc) = plt.subplots(
        2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}, constrained_layout=True
    )
    ax.semilogy(f, np.abs(frf.h[0, sel]), color="C1", lw=1.2, label="accelerometer 1 (in line with hammer)")
    ax.semilogy(f, np.abs(frf.h[1, sel]), color="C2", lw=1.2, label="accelerometer 2 (90 degrees)")
    seen: set[str] = set()
    for m in result.modes:
        color, label = KIND_STYLE.get(m.kind, KIND_STYLE["unclassified"])
        ax.axvline(m.frequency_hz, color=color, lw=0.9, ls="--", label=None if label in seen else label)
        seen.add(label)
        k = int(np.argmin(np.abs(frf.freq_hz - m.frequency_hz)))
        ax.annotate(
            f"{m.frequency_hz:.0f} Hz",
            (m.frequency_hz, float(np.max(np.abs(frf.h[:, k])))),
            textcoords="offset points",
            xytext=(3, 4),
            fontsize=8,
            color=color,
        )
    hoop = result.hoop
    title = "Impact test: FRFs (H1"
    title += f", {result.n_hits} hits averaged)" if result.n_hits > 1 else ", one hit)"
    if hoop is not None:
        title += f"; first hoop {hoop.frequency_hz:.1f} ± {hoop.expanded_uncertainty_hz:.2g} Hz (k=2)"
    ax.set_title(title, fontsize=10)
    ax.set_ylabel("|accelerance| ((m/s²)/N)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower right")
    axc.plot(f, frf.coherence[0, sel], color="C1", lw=1.0)
    axc.plot(f, frf.coherence[1, sel], color="C2", lw=1.0)
    axc.axhline(result.settings.min_coherence, color="0.5", lw=0.8, ls=":")
    axc.set_ylim(0, 1.05)
    axc.set_ylabel("coherence")
    axc.set_xlabel("frequency (Hz)")
    axc.grid(alpha=0.3)
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)
    return paths


def plot_tap(result: TapResult, path: str | Path) -> list[Path]:
    """The taps' summed power spectrum (log scale), the modes marked by kind, the first hoop named."""
    paths = figure_paths(path)
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    freq, power = result.spectrum
    sel = freq > 0
    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    ax.semilogy(freq[sel], np.sqrt(power[sel]), color="C1", lw=1.0, label="taps' spectrum (summed power)")
    seen: set[str] = set()
    for m in result.modes:
        color, label = KIND_STYLE.get(m.kind, KIND_STYLE["unclassified"])
        ax.axvline(m.frequency_hz, color=color, lw=0.9, ls="--", label=None if label in seen else label)
        seen.add(label)
    hoop = result.hoop
    ax.set_title(
        f"Tap test, {len(result.tap_times_s)} taps: first hoop {hoop.frequency_hz:.1f}"
        f" ± {hoop.expanded_uncertainty_hz:.2g} Hz (k=2)",
        fontsize=10,
    )
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("|X| (full scale)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="upper right")
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)
    return paths
