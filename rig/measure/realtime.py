"""Speeds while the shot is still in flight: feed crossings one at a time, hear speeds at once.

The tracker keeps every crossing in arrival order and re-derives the passes and speeds with the
batch functions (split_passes, shot_speeds) on each event, so the final answer is the batch answer
by construction: counter wrap, out-of-order delivery and doubled triggers are handled the same way.
A speed is first announced as soon as no later, in-order event can change it:
- inbound, once the inbound pass has reached gate 3 (the gate nearest the bat: before the impact);
- rebound, once the rebound has crossed gates 3 and 2, or reached gate 1.
After that, any change is reported at once: an event delivered late can revise an announced speed
(a new InboundKnown/ReboundKnown) or withdraw it (SpeedWithdrawn). finish() closes the window and
settles what is left (e.g. only the far inbound pair, because gate 3 never broke).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from rig.core.devices import GateConfig, GateCrossing
from rig.measure.speeds import (
    DOUBLE_TRIGGER_S,
    GatePasses,
    ShotDataError,
    ShotSpeeds,
    shot_speeds,
    split_passes,
)


@dataclass(frozen=True)
class InboundKnown:
    """The inbound speed at the bat, m/s (the near pair when it exists)."""

    v: float


@dataclass(frozen=True)
class ReboundKnown:
    """The rebound speed off the bat, m/s."""

    v: float


@dataclass(frozen=True)
class SpeedWithdrawn:
    """A late event showed an announced speed has no basis after all."""

    which: Literal["inbound", "rebound"]


Update = InboundKnown | ReboundKnown | SpeedWithdrawn


class ShotWindowClosed(ShotDataError):
    """A crossing arrived after finish(): it belongs to no shot this tracker can take."""


class ShotTracker:
    """Streaming speeds of one shot.

    add() never raises for bad data: while the crossings give no speeds (e.g. equal ticks on a
    pair) it withdraws what it announced and exposes `problem`; finish() raises it if it remains.
    """

    def __init__(
        self, gate_config: GateConfig, positions_m: Sequence[float], double_within_s: float = DOUBLE_TRIGGER_S
    ) -> None:
        self._cfg = gate_config
        self._positions = tuple(float(p) for p in positions_m)
        self._double_within_s = double_within_s
        self._crossings: list[GateCrossing] = []
        self._said: dict[str, float | None] = {"inbound": None, "rebound": None}
        self._closed = False
        self._problem: ShotDataError | None = None
        shot_speeds(GatePasses({}, {}, ()), self._positions, gate_config)  # refuses bad geometry now

    @property
    def crossings(self) -> tuple[GateCrossing, ...]:
        """Every crossing received, in arrival order."""
        return tuple(self._crossings)

    @property
    def passes(self) -> GatePasses:
        """The passes as the batch split sees the crossings so far."""
        return split_passes(self._crossings, self._cfg, self._double_within_s)

    @property
    def speeds(self) -> ShotSpeeds:
        """The speeds as the batch computation gives them for the crossings so far."""
        return shot_speeds(self.passes, self._positions, self._cfg)

    @property
    def problem(self) -> ShotDataError | None:
        """Why the crossings so far give no speeds (e.g. equal ticks on a pair); finish() raises it."""
        return self._problem

    @property
    def closed(self) -> bool:
        """True after finish()."""
        return self._closed

    def add(self, crossing: GateCrossing) -> list[Update]:
        """Take one crossing; return the speeds it makes known (or revises)."""
        if self._closed:
            raise ShotWindowClosed(f"crossing at gate {crossing.gate} after the shot window closed")
        self._crossings.append(crossing)
        try:
            passes = self.passes
            sp = shot_speeds(passes, self._positions, self._cfg)
        except ShotDataError as exc:
            # Not fatal yet: a later (out-of-order) event can still make the shot computable.
            self._problem = exc
            return self._say("inbound", None) + self._say("rebound", None)
        self._problem = None
        out: list[Update] = []
        if (sp.inbound is not None and 3 in passes.inbound) or self._said["inbound"] is not None:
            out += self._say("inbound", sp.inbound)
        rebound_settled = sp.rebound_near is not None or 1 in passes.rebound
        if (sp.rebound is not None and rebound_settled) or self._said["rebound"] is not None:
            out += self._say("rebound", sp.rebound)
        return out

    def finish(self) -> list[Update]:
        """Close the window: announce, revise or withdraw so the last word equals the batch result.

        Raises the ShotDataError the batch computation raises (the shot is void: re-shoot).
        """
        if self._closed:
            return []
        self._closed = True
        sp = self.speeds
        return self._say("inbound", sp.inbound) + self._say("rebound", sp.rebound)

    def _say(self, which: Literal["inbound", "rebound"], v: float | None) -> list[Update]:
        before = self._said[which]
        if v == before:
            return []
        self._said[which] = v
        if v is None:
            return [SpeedWithdrawn(which)]
        return [InboundKnown(v) if which == "inbound" else ReboundKnown(v)]
