"""The work-precision study: errors against a checked reference, costs, fits, plots and the CLI."""

from __future__ import annotations

import json
import math
import re

import pytest

from benchmarks.timing import best_time
from rig.core.errors import ParameterError, SolverError
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS
from rig.physics.reference import CollisionResult
from studies.accuracy import precision
from studies.accuracy.curve_cost import CurveTradeoffRow, curve_tradeoff
from studies.accuracy.first_step import first_step_effect
from studies.accuracy.precision import (
    REFERENCE_AGREEMENT,
    PrecisionRow,
    PrecisionStudy,
    reliable_rtol,
    tolerance_fit,
    work_precision,
)
from studies.accuracy.stopwatch import Stopwatch, stamped, stopwatch

ROW_KEYS = {"method", "rtol", "cor_error", "nfev", "time_s"}


@pytest.fixture(scope="module")
def study() -> PrecisionStudy:
    return stamped(lambda: work_precision(quick=True, timer=stopwatch(quick=True)))


@pytest.fixture(scope="module")
def curve_rows() -> tuple[CurveTradeoffRow, ...]:
    return curve_tradeoff(quick=True, timer=stopwatch(quick=True))


def _by_method(study: PrecisionStudy) -> dict[str, list[PrecisionRow]]:
    out: dict[str, list[PrecisionRow]] = {}
    for r in study.rows:
        out.setdefault(r.method, []).append(r)
    return out


def row(rtol: float, err: float, method: str = "X") -> PrecisionRow:
    return PrecisionRow(method, rtol, 1250.0, 60.8, 0.67, err, err, 100, 1e-3)


def test_quick_study_rows_are_finite_and_costed(study: PrecisionStudy) -> None:
    assert {"rig-DOP853", "DOP853", "RK45", "LSODA", "Radau"} <= set(study.methods())
    for r in study.rows:
        assert math.isfinite(r.cor_error) and r.cor_error >= 0.0, r
        assert math.isfinite(r.contact_time_error) and r.contact_time_error >= 0.0, r
        assert r.nfev > 0, r
        assert r.time_s > 0.0 and math.isfinite(r.time_s), r
        assert 0.0 < r.cor < 1.0, r


def test_tightest_tolerance_beats_loosest_for_every_method(study: PrecisionStudy) -> None:
    for method, rows in _by_method(study).items():
        loose = max(rows, key=lambda r: r.rtol)
        tight = min(rows, key=lambda r: r.rtol)
        assert tight.rtol < loose.rtol, method
        assert tight.cor_error < loose.cor_error, (method, loose, tight)
        assert tight.nfev > loose.nfev, (method, loose, tight)


def test_reference_methods_agree(study: PrecisionStudy) -> None:
    assert study.references
    for ref in study.references:
        assert ref.cor_disagreement <= REFERENCE_AGREEMENT
        assert ref.cor_disagreement == abs(ref.cor - ref.cor_radau)
        assert ref.contact_time_disagreement <= 1e-9
        # the 1250 Hz barrel returns the ball faster than the rigid wall's 0.4836 (numerics.md 1.1)
        assert 0.6 < ref.cor < 0.7


def test_compiled_kernel_is_accurate_at_tight_tolerance(study: PrecisionStudy) -> None:
    (r,) = [r for r in study.rows if r.method == "rig-DOP853" and r.rtol == 1e-10]
    assert r.cor_error <= 1e-8
    assert r.contact_time_error <= 1e-8


def test_dop853_tolerance_fit_exponent_is_positive(study: PrecisionStudy) -> None:
    fits = {f.method: f for f in study.tolerance_fits}
    assert fits["DOP853"].exponent > 0.0
    assert fits["DOP853"].points >= 2
    assert fits["DOP853"].constant > 0.0


def test_rows_and_study_are_json_safe(study: PrecisionStudy) -> None:
    rows = json.loads(json.dumps([r.as_dict() for r in study.rows], allow_nan=False))
    assert all(ROW_KEYS | {"hoop_hz", "speed", "contact_time_error"} <= set(r) for r in rows)
    whole = json.loads(json.dumps(study.as_dict(), allow_nan=False))
    assert {"rows", "references", "tolerance_fits", "environment"} <= set(whole)
    assert {"python", "numpy", "scipy", "numba", "platform", "cpu_count"} <= set(whole["environment"])
    rigid = PrecisionRow("DOP853", 1e-6, None, 60.8, 0.48, 1e-7, 1e-7, 10, 1e-3).as_dict()
    assert json.loads(json.dumps(rigid))["hoop_hz"] is None


def test_tolerance_fit_recovers_power_law_and_skips_zero_errors() -> None:
    rows = (*(row(rt, 3.0 * rt**0.8) for rt in (1e-4, 1e-6, 1e-8)), row(1e-10, 0.0))
    fit = tolerance_fit(rows)
    assert fit is not None
    assert fit.exponent == pytest.approx(0.8, rel=1e-9)
    assert fit.constant == pytest.approx(3.0, rel=1e-9)
    assert fit.points == 3
    assert tolerance_fit((row(1e-6, 1e-6), row(1e-8, 0.0))) is None
    # errors at or under the reference's own uncertainty are not fitted
    assert tolerance_fit(rows, floor=1e-5).points == 2  # type: ignore[union-attr]


def test_reliable_rtol_ignores_a_lucky_loose_tolerance() -> None:
    rows = (row(1e-4, 1e-9), row(1e-6, 1e-5), row(1e-8, 1e-9), row(1e-10, 1e-11))
    assert reliable_rtol(rows, 1e-8).rtol == 1e-8  # type: ignore[union-attr]
    assert reliable_rtol(rows, 1e-12) is None
    assert reliable_rtol(rows, 1.0).rtol == 1e-4  # type: ignore[union-attr]


def test_reference_disagreement_raises(monkeypatch: pytest.MonkeyPatch) -> None:
    def fake(
        imp: Impact, method: str = "DOP853", rtol: float = 1e-10, first_step: object = "auto"
    ) -> CollisionResult:
        cor = 0.5 if method == "DOP853" else 0.5 + 1e-9
        return CollisionResult(cor, 1e-3, -cor * imp.speed, (0.0,) * 4, 10, method, rtol)

    monkeypatch.setattr(precision, "solve_reference", fake)
    with pytest.raises(SolverError, match="disagree"):
        precision.reference_value(Impact(DEFAULT_PARAMS, 60.8, 1250.0))


def test_best_time_loops_fast_calls() -> None:
    calls = []
    t = best_time(lambda: calls.append(1), repeats=3, min_time_s=1e-3)
    assert 0.0 < t < 1e-3
    assert len(calls) > 3 * 2  # a calibrating call, then batches of several calls


def test_unknown_method_and_bad_repeats_are_refused() -> None:
    with pytest.raises(ParameterError, match="method"):
        work_precision(quick=True, methods=("Euler",))
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ParameterError, match="repeats"):
            Stopwatch(repeats=bad)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="repeats"):
        stopwatch(repeats=0)


def test_curve_tradeoff_rows(curve_rows: tuple[CurveTradeoffRow, ...]) -> None:
    assert len(curve_rows) == 4
    for r in curve_rows:
        assert r.time_s > 0.0 and r.grid_time_s > 0.0
        assert 0.0 <= r.max_eta_error < 1e-5
        # the optimum is refined at a fixed tight tolerance: about 1276 Hz at 60.8 m/s whatever the grid
        assert r.optimum_error_hz < 0.1
        assert 1200.0 < r.optimum_hz < 1350.0
        json.dumps(r.as_dict(), allow_nan=False)
    tight = [r for r in curve_rows if r.rtol == 1e-10]
    loose = [r for r in curve_rows if r.rtol == 1e-6]
    assert max(r.max_eta_error for r in tight) < min(r.max_eta_error for r in loose)


def test_plots_write_png_and_svg(
    study: PrecisionStudy, curve_rows: tuple[CurveTradeoffRow, ...], tmp_path
) -> None:
    from studies.accuracy.plots import plot_curve_tradeoff, plot_work_precision

    for paths in (
        plot_work_precision(study, tmp_path / "wp.png"),
        plot_curve_tradeoff(curve_rows, tmp_path / "sub" / "curve.svg"),
    ):
        assert {p.suffix for p in paths} == {".png", ".svg"}
        for p in paths:
            assert p.is_file() and p.stat().st_size > 1000, p
        png = next(p for p in paths if p.suffix == ".png")
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_tables(study: PrecisionStudy) -> None:
    from studies.accuracy.plots import fits_markdown, markdown_table, precision_table

    assert precision_table(study).row_count == len(study.rows)
    md = markdown_table(study)
    lines = md.strip().splitlines()
    assert len(lines) == 2 + len(study.rows)  # one case: one line per row, plus header and rule
    assert all(line.startswith("|") and line.endswith("|") for line in lines)
    for method in study.methods():
        assert f"| {method} |" in md
    assert len(markdown_table(study, rtols=[1e-4]).strip().splitlines()) == 2 + len(study.methods())
    assert "DOP853" in fits_markdown(study)


def test_cli_accuracy_json(capsys: pytest.CaptureFixture[str]) -> None:
    from studies.cli import main

    assert main(["accuracy", "--quick", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert isinstance(rows, list) and rows
    for r in rows:
        assert set(r) >= ROW_KEYS
        assert r["nfev"] > 0 and r["time_s"] > 0 and r["cor_error"] >= 0
    assert {r["method"] for r in rows} >= {"rig-DOP853", "DOP853", "Radau"}


def test_accuracy_doc_markdown_from_a_quick_run(
    study: PrecisionStudy, curve_rows: tuple[CurveTradeoffRow, ...]
) -> None:
    from benchmarks.accuracy_writer import build_markdown

    first = first_step_effect(
        Impact(DEFAULT_PARAMS, 60.8, 1250.0), rtols=(1e-6,), cor_ref=study.references[0].cor
    )
    # scipy with the kernel's first step is the kernel's own method and error control: same steps
    # (the kernel may add the 3 dense-output stages of its in-step check for a brief separation, and
    # retake the step that holds the end of contact, 12 stages a try, when it is too long for its
    # dense output: h * c1 |d|^b / mu > (8! rtol)^(1/8), docs/contacts.md)
    extra = first[0].kernel_nfev - first[0].nfev_kernel_step
    assert 0 <= extra % 12 <= 3 and extra <= 3 + 4 * 12
    assert first[0].cor_error_kernel_step == pytest.approx(first[0].kernel_cor_error, rel=1e-3, abs=1e-13)
    figures = {"main": "figures/a.png", "near": "figures/b.png", "curve": "figures/c.png"}
    md = build_markdown(study, study, curve_rows, first, None, 1.0, figures, 1e-6, (), "today")
    for heading in ("## Summary", "## How the study is done", "## Reading", "## Regenerating"):
        assert heading in md
    assert "benchmarks/accuracy_doc.py" in md and "figures/a.png" in md
    assert re.search(r"\bnan\b", md, re.IGNORECASE) is None
