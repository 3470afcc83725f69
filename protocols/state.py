"""A run's progress, rebuilt by folding its recorded events (so a killed run resumes exactly).

The fold lives next to the events (rig.core.run_state): the runner, the console and the report
share it. These names stay here for the procedures' code.
"""

from __future__ import annotations

from rig.core.run_state import RunState, ShotEntry, fold

__all__ = ["RunState", "ShotEntry", "fold"]
