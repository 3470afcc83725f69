"""From the valid hits to the verdict, and the model's cross-check of the measured value.

The decision rule (docs/procedures.md): with guarded acceptance a bat passes only when its mean
metric plus the expanded uncertainty k u stays within the limit; with the simple rule, when the
mean alone does. The model cross-check predicts the metric from the bat's hoop frequency: with a
calibration (rig model calibrate; named by the procedure or the rig config, recorded whole in
RunStarted) it gives the calibrated prediction interval and flags a bat outside it
(rig.population.crosscheck); without one it shows the raw prediction and flags nothing, because
the model's absolute level is not validated.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from rig.core.bat import Barrel, BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RigError
from rig.core.outcomes import RunVerdict, ShotOutcome, Verdict
from rig.measure.metrics import compute_metrics, recorded_terms
from rig.measure.model import OUTPUTS, ShotInputs, outputs
from rig.measure.tradeoff import tradeoff_table
from rig.measure.uncertainty import budget, u_with_scatter
from rig.physics import DEFAULT_PARAMS, CollisionParams, PivotedBat, predict_bat, rigid_cor
from rig.population.calfile import CalibrationFile, read_calibration
from rig.population.crosscheck import crosscheck_at
from rig.protocols.ball_terms import BallAdjustment, BallTerms, adjust, hit_balls, law_params, ratio
from rig.protocols.bpf_verdict import bpf_result
from rig.protocols.procedure import Procedure
from rig.protocols.run_inputs import air_density, uncertainty_model
from rig.protocols.state import RunState, ShotEntry

UNCALIBRATED = (
    "uncalibrated: the model's absolute value is not validated (the paper validates only normalized"
    " efficiency); the prediction is shown, nothing is flagged"
)


def verdict(p: Procedure, bat: BatSpec, state: RunState, config: RigConfig) -> RunVerdict:
    """Mean of the valid hits at the chosen location, its uncertainty, the decision, the cross-check."""
    loc = state.best_location_in
    hits = state.valid_shots("valid", loc)
    measured = [h.outcome for h in hits if h.outcome is not None and h.outcome.metric is not None]
    if not measured:
        raise RigError("no valid hits to decide on")
    values = [float(m.metric) for m in measured if m.metric is not None]
    n = len(values)
    mean = sum(values) / n
    inputs = [ShotInputs.recorded(m.inputs) for m in measured]
    model = uncertainty_model(p, config, state)
    per_bat = budget(inputs, model)
    per_hit = budget(inputs[0], model)
    name = p.metric.budget_output  # BBS's is e_A's, scaled below
    q = bat.impact_from_pivot_m(loc) if loc is not None else config.impact_from_pivot_m
    moi = float(state.moi.moi_kgm2) if state.moi else float(bat.moi_kgm2 or 0.0)
    by_ball = "bbcor" if p.metric.needs_ball_cor else p.standard  # a BPF's ball terms act on its BBCOR
    ball = ball_part(p, bat, state, hits, q, moi, by_ball)
    observed = [float(recorded_metrics(m)[name]) for m in measured]
    if ball is not None and name == by_ball:  # the scatter of what is averaged: corrected hits
        observed = [v + c for v, c in zip(observed, ball.corrections, strict=True)]
    u = u_with_scatter(per_bat, observed, name) if n >= 2 else per_bat.u_of(name)
    normalised = None
    if p.metric.needs_ball_cor:  # BBCOR and the lot's COR at the nominal ball; the COR's u taken once
        bbcor_hits = [float(recorded_metrics(m)["bbcor"]) for m in measured]
        values, normalised = bpf_result(p.metric.basis, bbcor_hits, u, ball, state, hits)
        mean, u_measured, u = sum(values) / n, u / normalised["ball_cor"], normalised["u"]
    else:
        u *= p.metric.scale(recorded_terms(recorded_metrics(measured[0])))  # 1 unless it is not the metric's
        u_measured = u
        if ball is not None:
            values = [v + c for v, c in zip(values, ball.corrections, strict=True)]
            mean = sum(values) / n
            u = math.hypot(u, ball.u)
    k = p.decision.coverage_k
    big_u = k * u
    if p.decision.rule == "guarded":
        passed = mean + big_u <= p.limit
        rule = f"guarded acceptance: PASS if mean + {k:g} u <= limit"
    else:
        passed = mean <= p.limit
        rule = "simple acceptance: PASS if mean <= limit"
    zone = (
        "pass" if passed else ("fail: within the guard band" if mean <= p.limit else "fail: above the limit")
    )
    law = ((state.setup or {}).get("ball") or {}).get("law")  # the run's ball law, if it named one
    v_in_mean = sum(_inbound(m) for m in measured) / n
    return RunVerdict(
        verdict=Verdict.PASS if passed else Verdict.FAIL,
        zone=zone,
        metric=p.standard,
        definition=p.metric.definition,
        mean=mean,
        u=u,
        U=big_u,
        coverage_k=k,
        limit=p.limit,
        decision_rule=rule,
        n_hits=n,
        hits=values,
        location_in=loc,
        impact_from_pivot_m=q,
        moi_kgm2=moi,
        edition=p.edition,
        budget=per_bat.as_dict(),
        ball={**ball.as_dict(), "u_measurement": u_measured} if ball is not None else None,
        bpf=normalised,
        drag=drag_summary(config, state, inputs, name, per_bat.value(name)),
        cross_check=cross_check(
            p,
            bat,
            v_in_mean,
            q,
            moi,
            mean,
            # a BPF: the measurement's part, the ball COR's u the prediction carries (taken once)
            u_measured if p.metric.needs_ball_cor else u,
            state.calibration,
            law,
            wall_cor(state)[:2] if p.metric.needs_ball_cor else None,
        ),
        tradeoff=[
            r.as_dict() for r in tradeoff_table(per_hit, name, max_hits=12, cycle_s=config.cannon_cycle_s)
        ],
    )


def wall_cor(state: RunState) -> tuple[float, float, str, str]:
    """The run's ball COR on the rigid wall, its standard u, the ball-cor run and the lot it came
    from (the ball terms RunStarted recorded); RigError if the run has none (a BPF needs it)."""
    terms = (state.setup or {}).get("ball") or {}
    cor, u = terms.get("wall_cor"), terms.get("wall_cor_u")
    if cor is None or u is None:
        raise RigError(
            "a BPF run needs its ball COR: the lot's ball-cor result (rig certify --ball-lot LOT), "
            "which this run did not record"
        )
    return float(cor), float(u), str(terms.get("wall_cor_run") or ""), str(terms.get("lot") or "")


def recorded_metrics(outcome: ShotOutcome) -> dict[str, float]:
    """A valid hit's metrics (a valid certification hit has them: a record without is damaged)."""
    if outcome.metrics is None:
        raise RigError("a valid hit without its metrics: a damaged record")
    return outcome.metrics


def _inbound(outcome: ShotOutcome) -> float:
    """A hit's inbound speed at the impact point (as measured at the gates in runs before drag)."""
    v = (
        outcome.inbound_at_impact_m_s
        if outcome.inbound_at_impact_m_s is not None
        else outcome.inbound_speed_m_s
    )
    if v is None:
        raise RigError("a valid hit without its inbound speed: a damaged record")
    return float(v)


def drag_summary(
    config: RigConfig, state: RunState, inputs: list[ShotInputs], name: str, corrected: float
) -> dict[str, Any]:
    """The drag correction's inputs (Cd, air) and what it changed in the mean of `name`."""
    index = OUTPUTS.index(name)
    plain = [
        float(outputs(replace(i, cd_in=0.0, cd_out=0.0).vector(), i.gates, i.ball_diameter_m)[index])
        for i in inputs
    ]
    a = config.air
    return {
        "applied": any(i.cd_in > 0.0 or i.cd_out > 0.0 for i in inputs) and inputs[0].air_density > 0.0,
        "drag_coefficient": a.drag_coefficient,
        "drag_coefficient_u": a.drag_coefficient_u,
        "rebound_drag_coefficient": a.rebound_drag_coefficient,
        "rebound_drag_coefficient_u": a.rebound_drag_coefficient_u,
        "ball_diameter_m": a.ball_diameter_m,
        "air": air_density(config, state).as_dict(),
        "output": name,
        "mean_uncorrected": sum(plain) / len(plain),
        "correction": corrected - sum(plain) / len(plain),
    }


def run_calibration(p: Procedure, config: RigConfig) -> dict[str, Any] | None:
    """The calibration a new run uses, as RunStarted records it (None: no calibration named).

    Named by the procedure (`calibration`) or the rig config ([model] calibration); both naming
    different files is refused, as are a file that does not load, another metric or another speed.
    The record holds the file's path, sha256 and whole content, so that a resumed run and a report
    made later use this very calibration whatever has become of the file.
    """
    by_config = config.model.named_by
    named = {k: v for k, v in (("procedure", p.calibration), (by_config, config.model.calibration)) if v}
    if not named:
        return None
    if len({str(Path(v).resolve()) for v in named.values()}) > 1:
        raise ConfigError(
            f"the procedure names calibration {named['procedure']} and the {by_config} {named[by_config]}:"
            " name one",
            source="calibration",
        )
    by, path = next(iter(named.items()))
    cal, data = read_calibration(path)  # the bytes read once: recorded as they were checked
    if cal.metric != p.standard:
        raise ConfigError(f"a {cal.metric} calibration; the procedure certifies {p.standard}", source=path)
    if abs(cal.speed_m_s - p.target_speed_m_s) > p.speed_tolerance_m_s:
        raise ConfigError(
            f"calibrated at {cal.speed_m_s:g} m/s; the procedure shoots at {p.target_speed_m_s:g} m/s",
            source=path,
        )
    if cal.ball is None and abs(cal.model_params.m1 - p.ball.mass_kg) > 1e-6:
        raise ConfigError(
            f"calibrated with {cal.model_params.m1:g} kg balls;"
            f" the procedure fires {p.ball.mass_kg:g} kg balls",
            source=path,
        )
    return {
        "path": str(path),
        "named_by": by,
        "sha256": hashlib.sha256(data).hexdigest(),
        "file": json.loads(data),
    }


def same_law(x: dict[str, float] | None, y: dict[str, float] | None) -> bool:
    """Whether two recorded ball laws' constants are one (None: the paper's ball)."""
    if x is None or y is None:
        return x is None and y is None
    return set(x) == set(y) and all(abs(x[n] - y[n]) <= 1e-12 * max(abs(x[n]), 1.0) for n in x)


def _uncalibrated(
    p: Procedure,
    bat: BatSpec,
    v_in: float,
    q: float,
    moi: float,
    measured: float,
    note: str,
    law: dict[str, float] | None = None,
) -> dict[str, Any]:
    hoop = None if bat.barrel is Barrel.WOOD else bat.hoop_hz
    params = CollisionParams.build(**{**DEFAULT_PARAMS.model_dump(), "m1": p.ball.mass_kg, **(law or {})})
    pred = predict_bat(params, v_in, hoop, PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q))
    # a BPF's prediction: the model ball's BBCOR over the same model ball's COR on a rigid wall
    own_cor = rigid_cor(params, p.target_speed_m_s) if p.metric.needs_ball_cor else None
    m = compute_metrics(v_in, pred.e_a * v_in, q, moi, p.ball.mass_kg, bat.length_m, ball_cor=own_cor)
    predicted = m.value(p.standard)
    if own_cor is not None:
        note += f"; predicted BPF = the model's BBCOR / its ball's rigid-wall COR {own_cor:.4f}"
    return {
        "calibrated": False,
        "predicted": predicted,
        "measured": measured,
        "difference": measured - predicted,
        "interval": None,
        "z": None,
        "hoop_hz": hoop,
        "model": "pivoted bat, rigid barrel" if hoop is None else "pivoted bat with hoop mode (Eqs. 1-2)",
        "flagged": None,
        "consistent": None,
        "note": note,
    }


def ball_part(
    p: Procedure,
    bat: BatSpec,
    state: RunState,
    hits: list[ShotEntry],
    q: float,
    moi: float,
    metric: str | None = None,
) -> BallAdjustment | None:
    """The ball's corrections and budget terms, for a run that recorded its ball terms (else None),
    in units of `metric` (default the procedure's)."""
    recorded = (state.setup or {}).get("ball")
    if recorded is None or moi <= 0.0:
        return None
    terms = BallTerms.model_validate(recorded)
    g = ratio(
        law_params(terms, p.ball.mass_kg),
        metric or p.standard,
        p.target_speed_m_s,
        q,
        moi,
        bat.length_m,
        None if bat.barrel is Barrel.WOOD else bat.hoop_hz,  # a solid barrel has no hoop mode
    )
    return adjust(terms, hit_balls(hits, state.environment, terms), g)


def cross_check(
    p: Procedure,
    bat: BatSpec,
    v_in: float,
    q: float,
    moi: float,
    measured: float,
    u: float | None = None,
    calibration: dict[str, Any] | None = None,
    law: dict[str, float] | None = None,
    ball_cor: tuple[float, float] | None = None,
) -> dict[str, Any]:
    """The model's prediction at the bat's hoop frequency next to the measured value (u: its k = 1 u;
    `ball_cor`: a BPF run's ball COR and its u, which the calibrated prediction divides by).

    With `calibration` (as run_calibration records it) the calibrated prediction interval and the
    flag; without, the uncalibrated prediction and no flag. `law`: the run's recorded ball law
    (`--ball`, or the lot's), which the prediction uses; a calibration made with another ball is
    not used (its barrel was fitted for that ball), the prediction is then uncalibrated.
    """
    if bat.hoop_hz is None and bat.barrel is not Barrel.WOOD:
        return {
            "predicted": None,
            "flagged": None,
            "note": "no hoop frequency in the bat file: no model cross-check",
        }
    if calibration is None:
        return _uncalibrated(p, bat, v_in, q, moi, measured, UNCALIBRATED, law)
    if bat.barrel is Barrel.WOOD or bat.hoop_hz is None:
        note = "the calibration is of the barrel's hoop mode; a wood barrel is rigid: " + UNCALIBRATED
        return _uncalibrated(p, bat, v_in, q, moi, measured, note, law)
    try:
        cal = CalibrationFile.model_validate(calibration["file"])
        made_with = None if cal.ball is None else dict(cal.ball["constants"])
        if not same_law(law, made_with):
            which = "the paper's ball" if made_with is None else "another ball law"
            note = f"the calibration was made with {which}, not this run's: {UNCALIBRATED}"
            return _uncalibrated(p, bat, v_in, q, moi, measured, note, law)
        c = crosscheck_at(
            cal,
            bat.hoop_hz,
            moi,
            q,
            bat.length_in,
            measured,
            u,
            p.cross_check_coverage,
            bat_id=bat.id,
            ball_cor=ball_cor,
        )
    except (RigError, ValueError, KeyError) as exc:  # the cross-check informs; it never stops a verdict
        errors = getattr(exc, "errors", None)  # a pydantic ValidationError: its first message
        reason = errors()[0]["msg"] if callable(errors) else str(exc).splitlines()[0]
        return _uncalibrated(
            p, bat, v_in, q, moi, measured, f"recorded calibration not usable ({reason}): {UNCALIBRATED}", law
        )
    prov = cal.provenance
    where = f" (outside the calibrated {prov.range_text()}: extrapolated)"
    note = (
        "measured performance outside the calibrated model's prediction interval: possibly an altered bat"
        " or a rig fault"
        if c.flagged
        else "measured performance consistent with the calibrated model at this hoop frequency"
    ) + (where if c.extrapolated else "")
    return {
        **c.as_dict(),
        "calibrated": True,
        "consistent": not c.flagged,
        "difference": measured - c.predicted,
        "model": f"pivoted bat with hoop mode (Eqs. 1-2), calibrated ({cal.variant})",
        "calibration": {
            "path": calibration["path"],
            "named_by": calibration["named_by"],
            "sha256": calibration["sha256"],
            "variant": cal.variant,
            "parameters": dict(cal.parameters),
            "uncertainty": dict(cal.uncertainty),
            "scatter": cal.scatter,
            "loo_rmse": cal.loo_rmse,
            "provenance": prov.model_dump(),
        },
        "note": note,
    }


def stage_verdict(
    p: Procedure, bat: BatSpec, state: RunState, config: RigConfig, purpose: str, hoop_hz: float | None
) -> RunVerdict:
    """The verdict of the valid hits of `purpose` at the chosen location (an accelerated break-in's
    stage), decided as the run's own, with the cross-check at the stage's hoop frequency (none where
    it was not measured: the new bat's would predict a barrel that rolling has changed)."""
    hits = [replace(s, purpose="valid") for s in state.shots if s.purpose == purpose]
    view = replace(state, shots=hits)
    stage_bat = bat.model_copy(update={"hoop_hz": hoop_hz})
    return verdict(p, stage_bat, view, config)
