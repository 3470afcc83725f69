"""Helpers for driving the operator's console headless with Textual's Pilot.

Tests wait on the console's own state (a prompt pending, the run ended), never on fixed sleeps.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import pytest
from textual.pilot import Pilot

from rig.core.bat import BatSpec
from rig.core.tomlfile import dump_toml
from rig.session import sim_config
from rig.tui import ConsoleSettings, RigConsole
from rig.tui.rigs import RigChoice
from rig.tui.run import RunScreen

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
QUICK = Path(__file__).parent / "quick-bbcor.toml"  # two locations, two hits, no ring check


@pytest.fixture
def make_settings(tmp_path: Path) -> Callable[..., ConsoleSettings]:
    """Console settings on a simulated scene with the sample bat and a fresh record store."""

    def make(scene: str = "ideal", procedure: str = "bbcor", **kw: object) -> ConsoleSettings:
        settings = ConsoleSettings.from_args(
            scene, None, tmp_path / "records.db", bat=str(SAMPLE_BAT), procedure=procedure
        )
        settings.poll_s = 0.25
        for key, value in kw.items():
            setattr(settings, key, value)
        return settings

    return make


def one_key_rig(folder: Path, scene: str = "ideal") -> RigChoice:
    """A rig file for a simulated scene whose lab chose the one key ([console] one_key = true)."""
    config = sim_config(scene, bat=BatSpec.load(SAMPLE_BAT))  # its devices are served in this process
    data = config.model_dump(mode="json", exclude_none=True) | {"console": {"one_key": True}}
    path = folder / "one-key-rig.toml"
    path.write_text(dump_toml(data), encoding="utf-8")
    return RigChoice("config", str(path))


async def until(pilot: Pilot, cond: Callable[[], object], what: str, timeout: float = 120.0) -> None:
    """Let the app run until `cond()` holds (at most `timeout` s: generous, since on a busy machine
    (seven runnable processes on two cores were seen) opening the run screen took more than 30 s)."""
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await pilot.pause(0.02)


def run_screen(app: RigConsole) -> RunScreen:
    """The (topmost) run screen."""
    return next(s for s in reversed(app.screen_stack) if isinstance(s, RunScreen))


async def start_run(pilot: Pilot) -> RunScreen:
    """Press s on the set-up screen and wait for the run screen."""
    app = pilot.app
    assert isinstance(app, RigConsole)
    await until(pilot, lambda: app.screen.query("#devices"), "the set-up screen")
    await pilot.press("s")
    await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")
    return run_screen(app)


async def answer_prompts(pilot: Pilot, screen: RunScreen, timeout: float = 300.0) -> None:
    """Until the run ends: confirm every fire (f) and pass every ring check, one prompt at a time (y)."""

    def actionable() -> bool:
        p = screen.operator.pending
        return not screen.running or (p is not None and (not p.is_fire or not screen.fire_block()))

    deadline = time.monotonic() + timeout
    while screen.running:
        assert time.monotonic() < deadline, "the run did not end in time"
        await until(pilot, actionable, "a prompt to answer")
        prompt = screen.operator.pending
        if not screen.running or prompt is None:
            continue
        await pilot.press("f" if prompt.is_fire else "y")
        await until(pilot, lambda p=prompt: screen.operator.pending is not p, "the answer to go through")
