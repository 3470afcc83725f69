"""The console cannot run the accelerated break-in's rolling prompts yet: it refuses the ABI in one line,
from the set-up (headless, at 80x24), from `rig tui --procedure abi`, and when resuming an ABI run."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path

import pytest
from textual.widgets import Static

from rig.certification import certify
from rig.cli import main
from rig.cli.rolling import ScriptedRoller
from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.protocols.abi import abi
from rig.protocols.control import RunControl
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.sim_break_in import SimBreakIn
from rig.store import Store
from rig.tui import ConsoleSettings, RigConsole
from rig.tui.jobs import NO_BREAK_IN, _prepared
from rig.tui.rigs import RunJob
from rig.tui.setup import SetupScreen
from tests.tui.conftest import until

SIZE = (80, 24)
COMPOSITE = Path(__file__).resolve().parents[2] / "protocols" / "examples" / "composite-bat.toml"


def test_the_set_up_refuses_the_break_in_in_one_line(make_settings: Callable[..., ConsoleSettings]) -> None:
    settings = make_settings("composite", procedure="abi", bat_path=str(COMPOSITE))

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: app.screen.query("#devices"), "the set-up screen")
            setup = app.screen
            assert isinstance(setup, SetupScreen)
            await pilot.press("s")
            await until(
                pilot,
                lambda: "accelerated break-in" in str(setup.query_one("#status", Static).render()),
                "the refusal",
            )
            shown = str(setup.query_one("#status", Static).render())
            assert NO_BREAK_IN in shown and "\n" not in shown.strip()
            assert isinstance(app.screen, SetupScreen)  # no run screen, no run

    asyncio.run(body())
    if settings.db.exists():
        with Store.open(settings.db, create=False) as store:
            assert not store.runs()


def test_rig_tui_refuses_the_break_in_before_it_starts(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tui", "--sim", "composite", "--procedure", "abi"]) == 2
    err = capsys.readouterr().err.strip()
    assert NO_BREAK_IN in err and "\n" not in err


def test_resuming_a_break_in_run_is_refused_in_one_line(tmp_path: Path) -> None:
    bat, control = BatSpec.load(COMPOSITE), RunControl()
    bench = SimBreakIn()

    def roll_then_stop(depth_in: float, passes: int) -> tuple[float, float]:
        control.abort("the lab closes for the night")
        return bench.roll(depth_in, passes)

    try:
        config = bench.attach(sim_config("composite", bat=bat))
        with Store.open(tmp_path / "records.db") as store:
            operator = ScriptedRoller(hands=roll_then_stop)
            out = certify(
                store, Procedure.load("bbcor"), bat, config, plan=abi, operator=operator, control=control
            )
            assert out.status == "interrupted"
            job = RunJob(Procedure.load("bbcor"), bat, config, "simulated", run_id=out.run_id)
            with pytest.raises(ConfigError) as caught:
                _prepared(store, job)
    finally:
        bench.close()
    assert NO_BREAK_IN in str(caught.value) and "\n" not in str(caught.value)
