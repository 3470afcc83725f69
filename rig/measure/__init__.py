"""Measurement maths: gate timestamps to speeds, metrics, uncertainty, shot validity. Pure."""

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
