"""The console's first paint, as a ratio to B (a fresh python importing numpy and scipy.integrate).

Each measurement is a new process: `rig tui --sim` through the CLI's own entry point, run
headless, with a hook that prints as soon as the set-up screen has been drawn once; the time is
taken in this process from just before the child starts to the moment that line arrives. B is
measured the same way in the same run, so the ratio holds on a slower or busier machine.

    python benchmarks/bench_startup_console.py [--repeat 5] [--target 1.2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1.2  # first paint <= 1.2 B (issue 14)
BASELINE = "import numpy, scipy.integrate; print('ready', flush=True)"

# Both children: the set-up screen prints 'ready' once it has been drawn, then the app exits.
PAINTED_HOOK = """
import rig.tui.setup as setup

on_mount = setup.SetupScreen.on_mount
def painted(screen):
    print("ready", flush=True)
    screen.app.exit()
def hooked(screen):
    screen.call_after_refresh(painted, screen)  # first: before the work the screen defers past its paint
    on_mount(screen)
setup.SetupScreen.on_mount = hooked
"""

# The child: `rig tui --sim --db DB`, headless, printing 'ready' once the first screen is drawn.
CONSOLE = (
    "import sys\nimport rig.tui.app as app\n"
    + PAINTED_HOOK
    + """run = app.RigConsole.run
app.RigConsole.run = lambda self, *a, **k: run(self, *a, **{**k, "headless": True})
from rig.cli import main
sys.exit(main(["tui", "--sim", "--db", sys.argv[1]]))
"""
)

# The same console started without the command line (rig.tui directly): what the console costs alone.
CONSOLE_ALONE = (
    "import sys\nfrom rig.tui import ConsoleSettings, RigConsole\n"
    + PAINTED_HOOK
    + 'RigConsole(ConsoleSettings.from_args("ideal", None, sys.argv[1])).run(headless=True)\n'
)


def time_to_ready(code: str, *args: str) -> float:
    """Seconds from starting `python -c code args` to its first line 'ready' (then it may finish)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    with subprocess.Popen(
        [sys.executable, "-c", code, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    ) as child:
        assert child.stdout is not None
        for line in child.stdout:
            if line.strip() == "ready":
                elapsed = time.perf_counter() - t0
                break
        else:
            child.wait()
            err = child.stderr.read() if child.stderr else ""
            raise RuntimeError(f"the child never got ready (exit {child.returncode}): {err[-2000:]}")
        child.communicate(timeout=60)
    return elapsed


def baseline_s(repeat: int) -> float:
    """B: the median time for a fresh python to import numpy and scipy.integrate."""
    return statistics.median(time_to_ready(BASELINE) for _ in range(repeat))


def console_first_paint_s(repeat: int, alone: bool = False) -> float:
    """The median time from process start to the console's first drawn screen (`rig tui --sim`;
    `alone`: started from rig.tui, without the command line's parser)."""
    with tempfile.TemporaryDirectory(prefix="rig-bench-") as tmp:
        db = str(Path(tmp) / "records.db")
        code = CONSOLE_ALONE if alone else CONSOLE
        return statistics.median(time_to_ready(code, db) for _ in range(repeat))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="processes per measurement (median)")
    ap.add_argument("--target", type=float, default=TARGET, help="the limit, as a multiple of B")
    args = ap.parse_args(argv)
    time_to_ready(BASELINE)  # warm the file cache once, for both
    b = baseline_s(args.repeat)
    paint = console_first_paint_s(args.repeat)
    alone = console_first_paint_s(args.repeat, alone=True)
    ratio = paint / b
    verdict = "ok" if ratio <= args.target else "OVER"
    print(f"B (python: import numpy, scipy.integrate): {b * 1e3:.0f} ms (median of {args.repeat})")
    target = f"target <= {args.target:g} B: {verdict}"
    print(f"console first paint, rig tui --sim: {paint * 1e3:.0f} ms = {ratio:.2f} B ({target})")
    print(f"  of which without the command line (rig.tui alone): {alone * 1e3:.0f} ms = {alone / b:.2f} B")
    return 0 if ratio <= args.target else 1


if __name__ == "__main__":
    raise SystemExit(main())
