"""SVG snapshots of the console's main screens at 80x24, and at 60x20 and 120x40 (baselines in
__snapshots__/).

What would vary between runs is held still: no cursor blink, no toasts, the store's clock frozen,
run ids counted instead of random, relative paths, the ideal scene (deterministic). Update the
baselines with `pytest tests/tui --snapshot-update`, then look at them.
"""

from __future__ import annotations

import itertools
import uuid
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import pytest
from rich.text import Text
from textual.pilot import Pilot
from textual.widgets import Input

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.simulators.urlhandler import reset_worlds
from rig.store import Store
from rig.tui import ConsoleSettings, RigConsole
from rig.tui.history import HistoryScreen, ReportView
from rig.tui.modals import TooSmallScreen
from rig.tui.setup import SetupScreen
from tests.tui.conftest import QUICK, ROOT, answer_prompts, start_run, until

SIZE = (80, 24)
FROZEN = datetime(2025, 3, 14, 9, 26, 53, tzinfo=UTC)
Snap = Callable[..., bool]


@pytest.fixture(autouse=True)
def steady(monkeypatch: pytest.MonkeyPatch) -> None:
    """Relative paths from the checkout, run ids and rig names counted from 1."""
    monkeypatch.chdir(ROOT)
    counter = itertools.count(1)
    monkeypatch.setattr(uuid, "uuid4", lambda: uuid.UUID(int=next(counter) << 96))
    reset_worlds()  # the counted rig names start again in every test
    monkeypatch.setattr("rig.tui.history._certificate_md", lambda record: None)  # the summary only


def settings(tmp_path: Path, procedure: str = "bbcor") -> ConsoleSettings:
    s = ConsoleSettings.from_args(
        "ideal", None, tmp_path / "records.db", "protocols/examples/sample-bat.toml", procedure
    )
    s.poll_s, s.clock = 0.1, lambda: FROZEN
    return s


def still(pilot: Pilot) -> None:
    """No blinking cursor, no toasts."""
    for field in pilot.app.screen.query(Input):
        field.cursor_blink = False
    pilot.app.clear_notifications()


async def devices_read(pilot: Pilot) -> None:
    setup = pilot.app.screen
    assert isinstance(setup, SetupScreen)
    await until(pilot, lambda: setup.report is not None, "the device check")
    still(pilot)


def test_setup_screen(snap_compare: Snap, tmp_path: Path) -> None:
    assert snap_compare(RigConsole(settings(tmp_path)), terminal_size=SIZE, run_before=devices_read)


def test_help_overlay(snap_compare: Snap, tmp_path: Path) -> None:
    async def help_open(pilot: Pilot) -> None:
        await devices_read(pilot)
        await pilot.press("question_mark")
        await pilot.pause()

    assert snap_compare(RigConsole(settings(tmp_path)), terminal_size=SIZE, run_before=help_open)


async def whole_run(pilot: Pilot) -> None:
    screen = await start_run(pilot)
    await answer_prompts(pilot, screen)
    await until(pilot, lambda: screen.live.prediction is not None, "the model's prediction")
    still(pilot)


def test_run_screen_at_the_verdict(snap_compare: Snap, tmp_path: Path) -> None:
    app = RigConsole(settings(tmp_path, procedure=str(QUICK.relative_to(ROOT))))
    assert snap_compare(app, terminal_size=SIZE, run_before=whole_run)


def test_run_screen_at_the_verdict_120x40(
    snap_compare: Snap, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The wide layout: the scan, the hits, the budget and the device traffic as well.

    The traffic's last lines depend on how often the cannon was polled while a prompt waited
    (timing), so here the panel shows a fixed line; test_sizes checks its content.
    """
    monkeypatch.setattr("rig.tui.render.traffic_panel", lambda live, lines=12: Text("(device traffic)"))
    app = RigConsole(settings(tmp_path, procedure=str(QUICK.relative_to(ROOT))))
    assert snap_compare(app, terminal_size=(120, 40), run_before=whole_run)


def test_too_small_notice_60x20(snap_compare: Snap, tmp_path: Path) -> None:
    async def notice(pilot: Pilot) -> None:
        await until(pilot, lambda: isinstance(pilot.app.screen, TooSmallScreen), "the notice")
        await pilot.pause()

    assert snap_compare(RigConsole(settings(tmp_path)), terminal_size=(60, 20), run_before=notice)


def test_history_screen(snap_compare: Snap, tmp_path: Path) -> None:
    s = settings(tmp_path)
    bat = BatSpec.load("protocols/examples/sample-bat.toml")
    with Store.open(s.db, clock=s.clock) as store:
        certify(store, Procedure.load(QUICK), bat, sim_config("ideal", bat=bat))

    async def history(pilot: Pilot) -> None:
        await devices_read(pilot)
        await pilot.press("h")
        await until(pilot, lambda: isinstance(pilot.app.screen, HistoryScreen), "the history")
        report = pilot.app.screen.query_one("#report-text", ReportView)
        await until(pilot, lambda: report.source.startswith("# Run "), "the report")
        still(pilot)

    assert snap_compare(RigConsole(s), terminal_size=SIZE, run_before=history)
