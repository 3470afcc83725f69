"""The set-up screen shows the chosen rig's control-chart state (docs/quality.md): no check runs yet,
phase I in progress (k of 20), in control, a signal awaiting acknowledgement (named, with the refusal
of certification until `rig check ack`), acknowledged.

The simulated ideal rig gives the same session mean every time (sigma 0), so the check run made on
a copy of its scene with other balls (same rig name, sim-ideal) signals at once.
"""

from __future__ import annotations

import asyncio
import shutil
from collections.abc import Callable
from pathlib import Path

from textual.widgets import Static

from rig.simulators.scene import SCENES_DIR
from rig.tui import ConsoleSettings, RigConsole
from rig.tui.rigs import chart_state
from rig.tui.setup import SetupScreen
from tests.quality.test_check_lab import REF_BAT
from tests.tui.conftest import until
from tests.unit.clirun import run_cli


def _devices(settings: ConsoleSettings) -> str:
    """The Devices box of the set-up screen once the devices (and the charts) are read."""
    shown: list[str] = []

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=(100, 30)) as pilot:
            await until(pilot, lambda: isinstance(app.screen, SetupScreen), "the set-up screen")
            screen = app.screen
            assert isinstance(screen, SetupScreen)
            await until(pilot, lambda: screen.report is not None, "the device check")
            await pilot.pause()
            shown.append(str(screen.query_one("#devices", Static).render()))

    asyncio.run(body())
    return " ".join(shown[0].split())


def test_the_set_up_screen_follows_the_charts(
    make_settings: Callable[..., ConsoleSettings], tmp_path: Path
) -> None:
    settings = make_settings()
    db = settings.db
    config = settings.rigs[0].config()
    assert "checks no check runs yet" in _devices(settings)  # no store yet
    ref = tmp_path / "ref.toml"
    ref.write_text(REF_BAT)
    check = ["check", "--bat", str(ref), "--db", str(db), "--hits", "2", "--json"]
    assert run_cli([*check, "--sim", "ideal"], db).code == 0
    assert chart_state(db, config) == ("building phase I (1 of 20 check runs)", False)
    for _ in range(19):
        assert run_cli([*check, "--sim", "ideal"], db).code == 0
    assert chart_state(db, config) == ("in control", False)
    other_balls = tmp_path / "balls" / "ideal.toml"  # the same rig, sim-ideal, another ball
    other_balls.parent.mkdir()
    shutil.copy(SCENES_DIR / "ideal.toml", other_balls)
    with other_balls.open("a") as f:
        f.write("\n[ball]\nc1 = 5100.0\n")
    assert run_cli([*check, "--sim", str(other_balls)], db).code == 0
    line, refused = chart_state(db, config)
    assert refused and line.startswith("SIGNAL awaiting acknowledgement: action limit: session 21")
    assert line.endswith("certification refused until `rig check ack`")
    shown = _devices(settings)
    assert line in shown  # on the first screen, as the store says
    ack = ["check", "ack", "--db", str(db), "--who", "Q. Manager", "--why", "balls replaced"]
    assert run_cli(ack, db).code == 0
    assert chart_state(db, config) == (
        "signal acknowledged by Q. Manager; in use until the next check run",
        False,
    )
    assert "signal acknowledged by Q. Manager" in _devices(settings)


def test_a_store_that_cannot_be_read_is_said_not_raised(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    settings = make_settings()
    settings.db.write_bytes(b"not a store")
    line, refused = chart_state(settings.db, settings.rigs[0].config())
    assert line.startswith("control charts not read: ") and not refused
    assert settings.db.read_bytes() == b"not a store"  # read only
