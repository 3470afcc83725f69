"""Measurement maths: gate timestamps to speeds, metrics, uncertainty, shot validity. Pure.

The names load on first use, so that reading the metric registry (rig.measure.registry) does not
import numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rig.core.lazy import lazy_names

if TYPE_CHECKING:
    from rig.measure.metrics import DEFAULT_SWING, MetricSet, SwingModel, compute_metrics
    from rig.measure.realtime import InboundKnown, ReboundKnown, ShotTracker, SpeedWithdrawn
    from rig.measure.speeds import GatePasses, ShotDataError, ShotSpeeds, shot_speeds, split_passes
    from rig.measure.tradeoff import TradeoffRow, hits_needed, tradeoff_table
    from rig.measure.uncertainty import (
        Budget,
        ShotInputs,
        UncertaintyModel,
        budget,
        monte_carlo,
        u_with_scatter,
    )
    from rig.measure.validity import Code, Invalidity, ValidityLimits, check_shot, is_valid

_WHERE = {
    "DEFAULT_SWING": "metrics",
    "MetricSet": "metrics",
    "SwingModel": "metrics",
    "compute_metrics": "metrics",
    "InboundKnown": "realtime",
    "ReboundKnown": "realtime",
    "ShotTracker": "realtime",
    "SpeedWithdrawn": "realtime",
    "GatePasses": "speeds",
    "ShotDataError": "speeds",
    "ShotSpeeds": "speeds",
    "shot_speeds": "speeds",
    "split_passes": "speeds",
    "TradeoffRow": "tradeoff",
    "hits_needed": "tradeoff",
    "tradeoff_table": "tradeoff",
    "Budget": "uncertainty",
    "ShotInputs": "uncertainty",
    "UncertaintyModel": "uncertainty",
    "budget": "uncertainty",
    "monte_carlo": "uncertainty",
    "u_with_scatter": "uncertainty",
    "Code": "validity",
    "Invalidity": "validity",
    "ValidityLimits": "validity",
    "check_shot": "validity",
    "is_valid": "validity",
}

__getattr__ = lazy_names(__name__, _WHERE)

__all__ = [
    "DEFAULT_SWING",
    "Budget",
    "Code",
    "GatePasses",
    "InboundKnown",
    "Invalidity",
    "MetricSet",
    "ReboundKnown",
    "ShotDataError",
    "ShotInputs",
    "ShotSpeeds",
    "ShotTracker",
    "SpeedWithdrawn",
    "SwingModel",
    "TradeoffRow",
    "UncertaintyModel",
    "ValidityLimits",
    "budget",
    "check_shot",
    "compute_metrics",
    "hits_needed",
    "is_valid",
    "monte_carlo",
    "shot_speeds",
    "split_passes",
    "tradeoff_table",
    "u_with_scatter",
]
