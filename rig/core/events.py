"""Session events: past-tense facts that flow upwards to the store, the UI and reports.

An event is a kind and a JSON-ready payload. Kinds in PERSISTED are written to the record store
(in order, each committed before the run goes on); the others are for live display only and can
be recomputed from persisted ones.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

RUN_STARTED = "RunStarted"
RUN_RESUMED = "RunResumed"
ENVIRONMENT_CHECKED = "EnvironmentChecked"
MOI_MEASURED = "MoiMeasured"
OPERATOR_PROMPTED = "OperatorPrompted"
OPERATOR_ANSWERED = "OperatorAnswered"
LOCATION_SET = "LocationSet"
SHOT_REQUESTED = "ShotRequested"  # intent, committed before FIRE: a resume never fires it twice
SHOT_FIRED = "ShotFired"  # raw gate ticks, recoil, device traffic: committed before derivation
SHOT_MEASURED = "ShotMeasured"
SHOT_REJECTED = "ShotRejected"
SHOT_LOST = "ShotLost"
SHOT_OVERRULED = "ShotOverruled"  # the operator rejected a valid shot on review
BALL_REPLACED = "BallReplaced"
LOCATION_CHOSEN = "LocationChosen"
RUN_FINISHED = "RunFinished"
RUN_INTERRUPTED = "RunInterrupted"
RIG_CHECKED = "RigChecked"  # the operator confirms the rig was checked: the re-shoot budget starts again
RUN_ENDED = "RunEnded"  # the run ended on the operator's word, with no verdict
SCAN_EXTENDED = "ScanExtended"  # a location added beyond the scan to bracket the maximum
TRAFFIC = "Traffic"

# live only
GATE_CROSSED = "GateCrossed"
INBOUND_MEASURED = "InboundMeasured"
REBOUND_MEASURED = "ReboundMeasured"
DEVICE_STATUS = "DeviceStatus"
RUN_PAUSED = "RunPaused"
RUN_CONTINUED = "RunContinued"

PERSISTED = frozenset(
    {
        RUN_STARTED,
        RUN_RESUMED,
        ENVIRONMENT_CHECKED,
        MOI_MEASURED,
        OPERATOR_PROMPTED,
        OPERATOR_ANSWERED,
        LOCATION_SET,
        SHOT_REQUESTED,
        SHOT_FIRED,
        SHOT_MEASURED,
        SHOT_REJECTED,
        SHOT_LOST,
        SHOT_OVERRULED,
        BALL_REPLACED,
        LOCATION_CHOSEN,
        RUN_FINISHED,
        RUN_INTERRUPTED,
        RIG_CHECKED,
        RUN_ENDED,
        SCAN_EXTENDED,
        TRAFFIC,
    }
)


@dataclass(frozen=True)
class RunEvent:
    """One fact about a run."""

    kind: str
    data: dict[str, Any] = field(default_factory=dict)

    @property
    def persisted(self) -> bool:
        """Whether the record store keeps this kind."""
        return self.kind in PERSISTED


Subscriber = Callable[[RunEvent], None]
