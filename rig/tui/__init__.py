"""The operator's console (Textual): a thin client of the session that listens to events.

`rig tui --sim [SCENE]` or `rig tui --config RIG.toml`; see docs/tui.md.
"""

from rig.tui.app import RigConsole
from rig.tui.rigs import ConsoleSettings, RigChoice, RunJob

__all__ = ["ConsoleSettings", "RigChoice", "RigConsole", "RunJob"]
