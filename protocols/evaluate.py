"""From a shot's raw record to its metrics, uncertainty and validity.

The verdict over the valid hits and the model cross-check are rig.protocols.verdict; the lab air and
the input distributions both use are rig.protocols.run_inputs. This module re-exports them, so that
`evaluate.shot`, `evaluate.verdict` and `evaluate.run_calibration` name the whole evaluation.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.devices import Recoil
from rig.core.outcomes import ShotOutcome
from rig.measure.metrics import compute_metrics
from rig.measure.model import ShotInputs, inbound_at_impact
from rig.measure.registry import MetricTerms
from rig.measure.speeds import ShotDataError, shot_speeds, split_passes
from rig.measure.uncertainty import budget
from rig.measure.validity import Invalidity, ValidityLimits, check_shot
from rig.protocols.outcome import concluded, learned_aim, no_data
from rig.protocols.procedure import Procedure
from rig.protocols.run_inputs import NOMINAL_AIR, air_density, drag_inputs, uncertainty_model
from rig.protocols.shot import ShotRecord
from rig.protocols.state import RunState
from rig.protocols.verdict import (
    UNCALIBRATED,
    cross_check,
    drag_summary,
    run_calibration,
    stage_verdict,
    verdict,
    wall_cor,
)


def _metric_u(p: Procedure, bud: dict[str, Any], terms: MetricTerms) -> float:
    """The u of the budget output the metric's registry entry names, carried to the metric."""
    return float(bud["outputs"][p.metric.budget_output]["u"]) * p.metric.scale(terms)


def shot(
    record: ShotRecord,
    p: Procedure,
    bat: BatSpec,
    state: RunState,
    failure: str,
    config: RigConfig | None = None,
) -> ShotOutcome:
    """Speeds, metrics, uncertainty and validity of one fired shot.

    With `config` the gate speeds are corrected for air drag to the impact point (the rig's Cd,
    the lab air's density) before the metrics; without it they are used as measured.
    """
    moi = float(state.moi.moi_kgm2) if state.moi else float(bat.moi_kgm2 or 0.0)
    q = record.impact_from_pivot_m
    reasons: list[Invalidity] = []
    out: dict[str, Any] = {"metric_name": p.standard, "metric": None, "u": None}
    try:
        passes = split_passes(record.crossings, record.gate_config)
        speeds = shot_speeds(passes, record.gate_positions_m, record.gate_config)
    except ShotDataError as exc:
        return no_data(out, exc, aim_factor=state.aim_factor)
    air = air_density(config, state) if config is not None else None
    v_in_bat: float | None = None  # the inbound speed at the bat, which the target is for
    if speeds.inbound is not None:
        v_in_bat = inbound_at_impact(
            passes, record.gate_positions_m, record.gate_config, p.ball.mass_kg, drag_inputs(config, air)
        )
    limits = ValidityLimits(speed_tolerance_m_s=p.speed_tolerance_m_s)
    recoil = None if record.recoil_rad_s is None else Recoil(record.recoil_rad_s)
    reasons = check_shot(
        speeds,
        passes,
        p.target_speed_m_s,
        recoil,
        q,
        moi,
        p.ball.mass_kg,
        limits,
        positions_m=record.gate_positions_m,
        inbound_at_impact_m_s=v_in_bat,
    )
    v_in, v_out = speeds.inbound, speeds.rebound
    out["inbound_speed_m_s"], out["rebound_speed_m_s"] = v_in, v_out
    out["aim_factor"] = state.aim_factor
    if v_in_bat is not None:
        out["aim_factor"] = learned_aim(state.aim_factor, p.target_speed_m_s, v_in_bat, state.aim_shots)
        out["aim_shots"] = state.aim_shots + 1
    if v_in is not None and v_out is not None and v_out > 0:
        inputs = ShotInputs.from_passes(
            passes,
            record.gate_positions_m,
            record.gate_config,
            q,
            moi,
            p.ball.mass_kg,
            drag_inputs(config, air),
        )
        hit_budget = budget(inputs, uncertainty_model(p, config, state, air))
        v_in_hit, v_out_hit = hit_budget.value("v_in"), hit_budget.value("v_out")  # at the impact point
        ball_cor = wall_cor(state)[0] if p.metric.needs_ball_cor else None  # a BPF's: the lot's COR
        m = compute_metrics(v_in_hit, v_out_hit, q, moi, p.ball.mass_kg, bat.length_m, ball_cor=ball_cor)
        out["inbound_at_impact_m_s"], out["rebound_at_impact_m_s"] = v_in_hit, v_out_hit
        bud = hit_budget.as_dict()
        value = m.value(p.standard)
        out.update(
            metrics=m.as_dict(),
            metric=value,
            u=_metric_u(p, bud, m.terms),
            budget=bud,
            inputs={k: v for k, v in asdict(inputs).items()},
        )
    return concluded(out, reasons, failure)


__all__ = [
    "NOMINAL_AIR",
    "UNCALIBRATED",
    "air_density",
    "cross_check",
    "drag_inputs",
    "drag_summary",
    "run_calibration",
    "shot",
    "stage_verdict",
    "uncertainty_model",
    "verdict",
]
