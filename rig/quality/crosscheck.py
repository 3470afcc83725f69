"""The model cross-check's residuals on control charts (ISO/IEC 17025 7.7.1 h: correlating different
characteristics of an item): each certified run's standardised residual, charted per bat model.

A point is one finished certification run whose RunFinished records a calibrated cross-check
(rig.protocols.verdict.cross_check): its z = (measured - predicted) / u, u = sqrt(u_model^2 +
u_scatter^2 + u_measured^2) the prediction's combined standard uncertainty (rig.population.
crosscheck), as recorded. Runs without one (no calibration, a wood barrel, no hoop frequency, a
calibration made with another ball) are counted, not charted; check runs (kind `check`, the
reference bat) are never read.

A series is one bat model under one calibration (a new calibration moves every prediction, so it
starts its own series). The bat model is the maker and model the run's RunStarted bat names, when
the bat file gave them; records that name none are grouped by the calibration alone (its file's
sha256), which is then the series' only identity. Its charts take the standard values the
calibration states, centre 0 and sigma 1 (rig.quality.charts.build(standard=...)): no phase I,
every run judged, so a calibration that does not fit this rig's bats from the first run on is seen
too; the residuals' own spread (moving range / 1.128) is shown beside it. A signal is shown, never a
block on certification (docs/quality.md).
"""

from __future__ import annotations

import itertools
import math
from collections import defaultdict
from dataclasses import asdict, dataclass
from typing import Any

from rig.core import events as ev
from rig.core.ball import BALL_TESTS
from rig.core.outcomes import RunVerdict
from rig.quality import CHECK_KIND
from rig.quality.charts import D2, Charts, Session, Signal, build
from rig.quality.records import rig_of
from rig.store import RUN_CREATED, Store

STANDARD = (0.0, 1.0)  # the standardised residual's centre and sigma, as the calibration states them
NO_MODEL = "the record names no bat model: grouped by the calibration"


@dataclass(frozen=True)
class Residual:
    """One certified run's cross-check, as recorded."""

    run_id: str
    bat_id: str
    rig: str
    t_utc: str
    model: str | None  # "maker model" from RunStarted's bat, None when the bat file gave neither
    calibration: str  # the calibration file's sha256
    calibration_path: str
    z: float
    measured: float | None
    predicted: float | None
    u_total: float | None
    flagged: bool | None


@dataclass(frozen=True)
class ResidualSeries:
    """One bat model's residuals under one calibration, oldest first, and their charts."""

    model: str | None
    calibration: str
    calibration_path: str
    residuals: tuple[Residual, ...]
    charts: Charts

    @property
    def key(self) -> str:
        """The series' name: the bat model (if recorded) and the calibration's sha256, 12 digits."""
        cal = f"calibration {self.calibration[:12]}"
        return cal if self.model is None else f"bat model {self.model}, {cal}"

    def observed_sigma(self) -> float | None:
        """The residuals' own spread, moving range / 1.128 (near 1 when the calibration's u is right)."""
        z = [r.z for r in self.residuals]
        if len(z) < 2:
            return None
        return math.fsum(abs(b - a) for a, b in itertools.pairwise(z)) / (len(z) - 1) / D2

    def describe(self, sig: Signal) -> str:
        """One line: the rule, the run (its place, id and bat), z and the limit."""
        r = self.residuals[sig.index - 1]
        return (
            f"{sig.rule}: run {sig.index} ({r.run_id[:12]}, bat {r.bat_id}, rig {r.rig}) "
            f"{'EWMA' if sig.rule == 'EWMA' else 'z'} {sig.value:.3f} beyond {sig.limit:.3f}"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the series, its residuals, the charts (design, limits, points, signals)."""
        data = self.charts.as_dict()
        for sig, shown in zip(self.charts.signals, data["signals"], strict=True):
            shown["text"] = self.describe(sig)
        return {
            "series": self.key,
            "bat_model": self.model,
            "grouped_by": "bat model and calibration" if self.model else NO_MODEL,
            "calibration_sha256": self.calibration,
            "calibration_path": self.calibration_path,
            "residual": "z = (measured - predicted) / sqrt(u_model^2 + u_scatter^2 + u_measured^2), recorded",
            "observed_sigma": self.observed_sigma(),
            "blocks_certification": False,
            "residuals": [asdict(r) for r in self.residuals],
            **data,
        }


def _model(started: dict[str, Any]) -> str | None:
    bat = started.get("bat")
    if not isinstance(bat, dict):
        return None
    named = [
        str(bat[k]).strip() for k in ("maker", "model") if isinstance(bat.get(k), str) and bat[k].strip()
    ]
    return " ".join(named) or None


def _residual(store: Store, run_id: str, bat_id: str, t_utc: str) -> Residual | None:
    """The run's calibrated cross-check as a residual, or None when it has none."""
    entries = store.entries(run_id, kinds=[RUN_CREATED, ev.RUN_STARTED, ev.RUN_FINISHED])
    finished = [e for e in entries if e.kind == ev.RUN_FINISHED]
    if not finished:
        return None
    cc = RunVerdict.from_payload(finished[-1].payload, ev.RUN_FINISHED).cross_check or {}
    z = cc.get("z")
    cal = cc.get("calibration")
    if cc.get("calibrated") is not True or not isinstance(z, int | float) or not math.isfinite(z):
        return None
    if not isinstance(cal, dict) or not isinstance(cal.get("sha256"), str):
        return None
    created = next((e for e in entries if e.kind == RUN_CREATED), None)
    started = next((e.payload for e in entries if e.kind == ev.RUN_STARTED), {})

    def num(name: str) -> float | None:
        v = cc.get(name)
        return float(v) if isinstance(v, int | float) else None

    flagged = cc.get("flagged")
    return Residual(
        run_id, bat_id, rig_of(created), t_utc, _model(started), cal["sha256"], str(cal.get("path", "")),
        float(z), num("measured"), num("predicted"), num("u_total"),
        flagged if isinstance(flagged, bool) else None,
    )  # fmt: skip


def residual_series(store: Store, rig: str | None = None) -> tuple[list[ResidualSeries], list[str]]:
    """Every (bat model, calibration) series of the store's certified runs (of `rig`, or all rigs),
    oldest run first, charted with the standard values; and notes on the runs left out."""
    grouped: dict[tuple[str | None, str], list[Residual]] = defaultdict(list)
    without = 0
    for run in store.runs():
        if run.status != "finished" or run.procedure in (CHECK_KIND, ev.ONE_SHOT_KIND, *BALL_TESTS):
            continue
        r = _residual(store, run.run_id, run.bat_id, run.started_utc)
        if r is None:
            without += 1
        elif rig in (None, r.rig):
            grouped[(r.model, r.calibration)].append(r)
    series = [
        ResidualSeries(model, cal, rs[-1].calibration_path, tuple(rs),
                       build([Session(r.run_id, (r.z,), r.t_utc) for r in rs], standard=STANDARD))
        for (model, cal), rs in grouped.items()
    ]  # fmt: skip
    notes = []
    if without:
        notes.append(
            f"{without} finished run(s) with no calibrated cross-check (no calibration, a wood barrel, no "
            "hoop frequency, a calibration made with another ball): not charted"
        )
    return series, notes
