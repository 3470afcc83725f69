"""The certificate's figures (matplotlib Agg): location scan, valid hits, model curve with the bat.

Each plot works from the run record alone (`rig.report.record.run_record`) and is skipped (None)
when the record lacks what it needs, e.g. an interrupted run has no verdict to plot. The figures
are drawn only when asked for: PNG files (`write_figures`) or SVG text in memory (`svg_figures`,
what the HTML certificate embeds); matplotlib loads on the first drawing, not on import.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from rig.core.errors import RigError
from rig.core.units import INCH
from rig.measure import registry
from rig.measure.metrics import compute_metrics, recorded_terms
from rig.physics import DEFAULT_PARAMS, PivotedBat, fast, rigid_cor
from rig.physics.bat import impact_for

HOOP_RANGE_HZ = (800.0, 8000.0)
CURVE_POINTS = 60
CURVE_RTOL = 1e-8  # far below the rig's resolution; keeps the 60-point batch well under a second
_DPI = 110
SVG_SALT = "rig-certificate"  # fixed ids in the SVG text: the same record gives the same document


def _pyplot() -> Any:
    """matplotlib's pyplot on the Agg backend (no display), loaded on first use."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def metric_label(name: str | None) -> str:
    """How a metric is named in text and tables (its registry label)."""
    return registry.label(name)


def axis_label(name: str | None) -> str:
    """A metric's name with its unit, for plot axes."""
    return registry.heading(name)


def unit_suffix(name: str | None) -> str:
    """' m/s' after a value of a metric with a unit, '' for a ratio."""
    unit = registry.unit(name)
    return f" {unit}" if unit else ""


def budget_scale(record: dict[str, Any]) -> float | None:
    """The factor from the recorded budget output's u to the verdict metric's (its registry u_scale,
    e.g. BBS's V_pitch + V_bat) for the averaged hits, from their metrics; 1 when it is the metric."""
    entry = registry.find((record.get("verdict") or {}).get("metric"))
    if entry is None or entry.u_scale is None:
        return 1.0
    for s in certification_hits(record):
        m = s.get("metrics") or {}
        if m.get("k") is not None and m.get("v_bat") is not None:
            return entry.u_scale(recorded_terms(m))
    return None


def certification_hits(record: dict[str, Any]) -> list[dict[str, Any]]:
    """The valid certification hits the verdict averaged (at its chosen location)."""
    loc = (record.get("verdict") or {}).get("location_in")
    return [
        s
        for s in record.get("shots", [])
        if s.get("status") == "valid" and s.get("purpose") == "valid" and s.get("location_in") == loc
    ]


def _save(fig: Any, path: Path) -> Path:
    """The figure as a PNG file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI, metadata={"Software": None})
    _pyplot().close(fig)
    return path


def _svg(fig: Any) -> str:
    """The figure as SVG text (vector: it scales for print), with no date and fixed ids."""
    import matplotlib

    fig.tight_layout()
    out = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": SVG_SALT}):
        fig.savefig(out, format="svg", metadata={"Date": None, "Creator": None})
    _pyplot().close(fig)
    return out.getvalue()


def _limit_line(ax: Any, limit: Any) -> None:
    if isinstance(limit, int | float):
        ax.axhline(limit, color="C3", lw=1.2, ls="--", label=f"limit {limit:g}")


def plot_scan(record: dict[str, Any]) -> Any | None:
    """Metric against distance from the barrel end: valid scan shots, scan means, chosen location."""
    shots = [s for s in record.get("shots", []) if s.get("purpose") == "scan" and s.get("status") == "valid"]
    if not shots:
        return None
    name = (record.get("procedure") or {}).get("standard")
    fig, ax = _pyplot().subplots(figsize=(6.4, 3.8))
    ax.plot(
        [s["location_in"] for s in shots], [s["metric"] for s in shots], "o", color="C0", label="valid shot"
    )
    scan = (record.get("location") or {}).get("scan") or {}
    if scan:
        locs = sorted(scan, key=float)
        ax.plot([float(k) for k in locs], [scan[k] for k in locs], "-", color="C0", lw=1, alpha=0.6)
    chosen = (record.get("location") or {}).get("from_barrel_end_in")
    if chosen is not None:
        ax.axvline(chosen, color="C2", lw=1.2, label=f"chosen: {chosen:g} in")
        if str(chosen) in scan:
            ax.plot([chosen], [scan[str(chosen)]], "*", ms=14, color="C2")
    _limit_line(ax, (record.get("procedure") or {}).get("limit"))
    ax.set_xlabel("impact point: distance from the barrel end (in)")
    ax.set_ylabel(axis_label(name))
    ax.set_title("Location scan")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def plot_hits(record: dict[str, Any]) -> Any | None:
    """The valid hits the verdict averaged, with their mean, the +-U band and the limit."""
    v = record.get("verdict") or {}
    hits = certification_hits(record)
    if not hits or v.get("mean") is None:
        return None
    fig, ax = _pyplot().subplots(figsize=(6.4, 3.8))
    idx = [s["index"] for s in hits]
    ax.errorbar(
        idx,
        [s["metric"] for s in hits],
        yerr=[s.get("u") or 0.0 for s in hits],
        fmt="o",
        capsize=3,
        color="C0",
        label="valid hit (+- u)",
    )
    corrections = (v.get("ball") or {}).get("corrections") or []
    corrected = len(corrections) == len(hits) and any(c for c in corrections)
    if corrected:  # the result averages the hits corrected for their balls (certificate, Balls)
        ax.plot(
            idx,
            [s["metric"] + c for s, c in zip(hits, corrections, strict=True)],
            "o",
            mfc="none",
            color="C1",
            label="corrected for its ball",
        )
    mean, big_u = v["mean"], v.get("U") or 0.0
    what = "mean of the corrected hits" if corrected else "mean"
    ax.axhline(mean, color="C0", lw=1.2, label=f"{what} {mean:.4g}")
    ax.axhspan(
        mean - big_u,
        mean + big_u,
        color="C0",
        alpha=0.15,
        label=f"mean +- U (k = {v.get('coverage_k', 2):g})",
    )
    _limit_line(ax, v.get("limit"))
    ax.set_xticks(idx)
    ax.set_xlabel("shot number")
    ax.set_ylabel(axis_label(v.get("metric")))
    ax.set_title(f"Valid hits at {v.get('location_in')} in from the barrel end: {v.get('verdict')}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def model_curve(record: dict[str, Any], hoops: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The model's metric at each hoop frequency, and with a rigid barrel, for this bat and run.

    Same model and inputs as the verdict's cross-check: pivoted bat (MOI, impact point Q), the mean
    inbound speed of the averaged hits, the procedure's ball mass. None if the record cannot say.
    """
    v = record.get("verdict") or {}
    hits = certification_hits(record)
    bat, proc = record.get("bat") or {}, record.get("procedure") or {}
    name = v.get("metric")
    needed = (v.get("mean"), v.get("moi_kgm2"), v.get("impact_from_pivot_m"), bat.get("length_in"))
    if not hits or name is None or any(x is None for x in needed):
        return None
    v_in = sum(s.get("inbound_at_impact_m_s") or s["inbound_speed_m_s"] for s in hits) / len(hits)
    q, moi, m_ball = v["impact_from_pivot_m"], v["moi_kgm2"], (proc.get("ball") or {}).get("mass_kg", 0.145)
    length = bat["length_in"] * INCH
    params = DEFAULT_PARAMS.model_copy(update={"m1": m_ball})
    offset = 0.0
    cc = record.get("cross_check") or {}
    if cc.get("calibrated") is True:  # the calibrated model, at the calibration's speed and ball
        from rig.population.calibrate import model_params
        from rig.population.model import BALL_MASS_KG, SPEED_M_S

        fitted = (cc.get("calibration") or {}).get("parameters") or {}
        params, v_in, m_ball, offset = (
            model_params(fitted),
            SPEED_M_S,
            BALL_MASS_KG,
            fitted.get("offset", 0.0),
        )
    pivoted = PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)
    entry = registry.find(name)
    # a BPF's curve: the model ball's BBCOR over the same ball's COR on a rigid wall (as the cross-check)
    own_cor = rigid_cor(params, v_in) if entry is not None and entry.needs_ball_cor else None

    def metric(e_a: float) -> float:
        value = compute_metrics(v_in, e_a * v_in, q, moi, m_ball, length, ball_cor=own_cor).as_dict()[name]
        return float("nan") if value is None else value + offset

    try:
        impacts = [impact_for(params, v_in, float(f), pivoted) for f in hoops]
        cor, _ = fast.solve_batch(impacts, rtol=CURVE_RTOL)
        rigid, _ = fast.solve_batch([impact_for(params, v_in, None, pivoted)], rtol=CURVE_RTOL)
    except RigError:
        return None
    return np.array([metric(float(e)) for e in cor]), metric(float(rigid[0]))


def plot_model(record: dict[str, Any]) -> Any | None:
    """Predicted metric against hoop frequency, this bat's measured value (+-U) on it, the limit."""
    v = record.get("verdict") or {}
    hoop = (record.get("bat") or {}).get("hoop_hz")
    lo, hi = HOOP_RANGE_HZ
    if hoop is not None:
        lo, hi = min(lo, 0.8 * hoop), max(hi, 1.2 * hoop)
    hoops = np.linspace(lo, hi, CURVE_POINTS)
    curve = model_curve(record, hoops)
    if curve is None:
        return None
    values, rigid = curve
    fig, ax = _pyplot().subplots(figsize=(6.4, 3.8))
    calibrated = (record.get("cross_check") or {}).get("calibrated") is True
    what = "calibrated model" if calibrated else "model (uncalibrated)"
    ax.plot(hoops, values, "-", color="C0", lw=1.6, label=f"{what}: pivoted bat with hoop mode")
    ax.axhline(rigid, color="0.5", lw=0.9, ls=":", label="model: rigid barrel")
    mean, big_u = v["mean"], v.get("U") or 0.0
    if hoop is not None:
        ax.errorbar(
            [hoop],
            [mean],
            yerr=[big_u],
            fmt="s",
            color="C1",
            capsize=4,
            ms=7,
            zorder=4,
            label=f"this bat: measured +- U at {hoop:g} Hz",
        )
        cc = record.get("cross_check") or {}
        predicted, interval = cc.get("predicted"), cc.get("interval")
        if predicted is not None and interval:
            spread = [[predicted - interval[0]], [interval[1] - predicted]]
            cover = f"{100 * cc.get('coverage', 0.95):g} %"
            ax.errorbar(
                [hoop],
                [predicted],
                yerr=spread,
                fmt="x",
                color="C0",
                ms=9,
                capsize=6,
                label=f"calibrated model at this bat, {cover} prediction interval",
            )
        elif predicted is not None:
            ax.plot([hoop], [predicted], "x", color="C0", ms=9, label="model at this bat")
    else:
        wood = (record.get("bat") or {}).get("barrel") == "wood"
        band = "this bat: measured +- U" + (" (wood: compare the rigid barrel)" if wood else " (no hoop Hz)")
        ax.axhspan(mean - big_u, mean + big_u, color="C1", alpha=0.25, label=band)
    _limit_line(ax, v.get("limit"))
    ax.set_xlabel("hoop frequency (Hz)")
    ax.set_ylabel(axis_label(v.get("metric")))
    ax.set_title("Collision model and this bat")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


FIGURES = (
    (
        "scan",
        "location-scan.png",
        plot_scan,
        "Location scan: metric against the impact point, chosen location",
    ),
    ("hits", "valid-hits.png", plot_hits, "Valid hits with their mean, the +-U band and the limit"),
    ("model", "model-curve.png", plot_model, "Model prediction against hoop frequency, with this bat"),
)


def write_figures(record: dict[str, Any], figures_dir: Path) -> dict[str, tuple[Path, str]]:
    """Draw every figure the record supports into figures_dir; key -> (PNG path, caption)."""
    out: dict[str, tuple[Path, str]] = {}
    for key, filename, plot, caption in FIGURES:
        fig = plot(record)
        if fig is not None:
            out[key] = (_save(fig, figures_dir / filename), caption)
    return out


def svg_figures(record: dict[str, Any]) -> dict[str, tuple[str, str]]:
    """Every figure the record supports as SVG text, written nowhere; key -> (SVG, caption)."""
    out: dict[str, tuple[str, str]] = {}
    for key, _filename, plot, caption in FIGURES:
        fig = plot(record)
        if fig is not None:
            out[key] = (_svg(fig), caption)
    return out
