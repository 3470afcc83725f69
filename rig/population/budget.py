"""What a calibration may spend: a time limit, a cap on each fit's model evaluations, progress lines.

A calibration on data the model family cannot describe once ran for more than 25 minutes without
a word. Every model evaluation of the fit ticks the budget; past the time limit the calibration
stops with CalibrationStopped, one line saying where it was and how to give it more time.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from rig.core.errors import RigError

DEFAULT_MAX_SECONDS = 600.0  # `rig model calibrate --max-seconds`
MAX_EVALUATIONS = 400  # of the model, per fit: a fit not converged by then is left out with a note


class CalibrationStopped(RigError):
    """The calibration reached its time limit; the message says where and how to allow more."""


@dataclass
class Budget:
    """The time limit of one calibration, its progress sink, and the model evaluations spent."""

    max_seconds: float = DEFAULT_MAX_SECONDS
    progress: Callable[[str], None] | None = None
    started: float = field(default_factory=time.monotonic)
    evaluations: int = 0
    doing: str = "starting"

    def elapsed(self) -> float:
        """Seconds since the calibration started."""
        return time.monotonic() - self.started

    def tick(self) -> None:
        """One model evaluation; CalibrationStopped past the time limit."""
        self.evaluations += 1
        if self.elapsed() > self.max_seconds:
            raise CalibrationStopped(
                f"calibration stopped at its time limit of {self.max_seconds:g} s while {self.doing}"
                f" ({self.evaluations} model evaluations); --max-seconds allows more"
            )

    def say(self, doing: str, done: str | None = None) -> None:
        """Record what is being done, and print a progress line if a sink is set."""
        self.doing = doing
        if self.progress is not None:
            self.progress(f"calibrate [{self.elapsed():6.1f} s]: {done or doing}")
