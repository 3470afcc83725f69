"""The console's first screen loads only what it shows: no plotting, no solver, no run machinery.

A fresh process starts the console headless and, as soon as the set-up screen has been drawn
once, lists which heavy modules are loaded. (The time itself is benchmarks/bench_startup_console.py.)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from tests.tui.conftest import ROOT, SAMPLE_BAT

HEAVY = (
    "matplotlib",
    "scipy",
    "scipy.integrate",
    "numba",
    "rig.certification",
    "rig.protocols.runner",
    "rig.report",
)

CHILD = """
import json, sys
from rig.tui import ConsoleSettings, RigConsole
import rig.tui.setup as setup

on_mount = setup.SetupScreen.on_mount
def painted(screen):
    loaded = [m for m in json.loads(sys.argv[1]) if m in sys.modules]
    print(json.dumps({"loaded": loaded, "bat": screen.query_one("#bat-id").value}), flush=True)
    screen.app.exit()
def hooked(screen):
    screen.call_after_refresh(painted, screen)  # first: before the work the screen defers past its paint
    on_mount(screen)
setup.SetupScreen.on_mount = hooked
settings = ConsoleSettings.from_args("ideal", None, sys.argv[2], bat=sys.argv[3])
RigConsole(settings).run(headless=True)
"""


def test_first_paint_loads_no_plotting_solver_or_run_machinery(tmp_path: object) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(HEAVY), str(tmp_path) + "/r.db", str(SAMPLE_BAT)],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        cwd=ROOT,
        check=True,
    )
    first = json.loads(out.stdout.splitlines()[0])
    assert first["bat"]  # the screen was drawn with the bat loaded from --bat
    assert first["loaded"] == []
