"""A ball fit as the ball-law file (rig.physics.ball_law.BallLaw), with its provenance."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime

from rig.ball.fit import SELECTION, BallFitResult, model_ccor, speed_levels
from rig.core.version import __version__
from rig.measure.selection import variant_rows
from rig.physics.ball_law import BALL_NAMES, BallLaw, BallProvenance

PAPER = "the founding paper's value (Sutton and Sherwood 2010)"


def weighting(result: BallFitResult) -> str:
    """How the points were weighted and where sigma comes from, in one sentence."""
    if result.data.weighted:
        return "weights 1/u_ccor^2; covariance (J^T W J)^-1 times the Birge ratio chi2/(n-p) when above 1"
    return "equal weights; covariance s^2 (J^T J)^-1 with s the residual scatter (n - p degrees of freedom)"


def ball_law(
    result: BallFitResult,
    blob: bytes,
    data_file: str,
    lot: str | None = None,
    fixed_sources: Mapping[str, str] | None = None,
    runs: Sequence[str] = (),
) -> BallLaw:
    """The file's contents: constants, chosen variant, covariance, scores, points and provenance."""
    fit = result.fit
    params = result.params
    data = result.data
    predicted = model_ccor(params, data.speed)
    loo = result.reports[result.chosen].loo_errors
    variants = variant_rows(result.reports)
    sources = dict(fixed_sources or {})
    fixed = {n: sources.get(n, PAPER) for n in BALL_NAMES if n not in fit.names}
    return BallLaw(
        constants={n: float(getattr(params, n)) for n in BALL_NAMES},
        variant=result.chosen,
        parameters=dict(fit.values),
        uncertainty=fit.errors(),
        covariance=fit.covariance.tolist(),
        correlation_ab=fit.correlation("a", "b"),
        scatter=fit.scatter,
        loo_rmse=result.reports[result.chosen].loo_rmse,
        dof=fit.dof,
        weighting=weighting(result),
        selection=SELECTION,
        variants=variants,
        points=[
            {
                "speed_m_s": float(s),
                "ccor": float(c),
                "u_ccor": float(1.0 / w) if data.weighted else None,
                "group": data.group_names[g],
                "model": float(p),
                "residual": float(c - p),
                "loo_error": float(e),
            }
            for s, c, w, g, p, e in zip(
                data.speed, data.ccor, data.weight, data.groups, predicted, loo, strict=True
            )
        ],
        notes=list(result.notes),
        provenance=BallProvenance(
            data_file=data_file,
            data_sha256=hashlib.sha256(blob).hexdigest(),
            lot=lot,
            runs=list(runs),
            n_points=data.n,
            n_balls=data.n_balls,
            n_speeds=len(speed_levels(data.speed.tolist())),
            speed_min_m_s=float(data.speed.min()),
            speed_max_m_s=float(data.speed.max()),
            created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
            software=f"rig {__version__}",
            fixed=fixed,
        ),
    )
