"""`rig.protocols.evaluate` names the whole evaluation: the shot here, verdict and cross-check re-exported."""

from __future__ import annotations

from rig.protocols import evaluate, run_inputs, verdict


def test_evaluate_re_exports_the_verdict_and_the_run_inputs_unchanged() -> None:
    assert evaluate.verdict is verdict.verdict
    assert evaluate.run_calibration is verdict.run_calibration
    assert evaluate.cross_check is verdict.cross_check
    assert evaluate.drag_summary is verdict.drag_summary
    assert evaluate.air_density is run_inputs.air_density
    assert evaluate.uncertainty_model is run_inputs.uncertainty_model
    assert set(evaluate.__all__) >= {"shot", "verdict", "run_calibration", "cross_check"}
    assert all(callable(getattr(evaluate, name)) for name in ("shot", "verdict", "run_calibration"))
