"""The console on a rig of real-instrument drivers (the three twins): its keys never fire the
cannon with an interlock open, through the Modbus PLC driver, with the door open while the shot
waits and with the door opening right after ARM (the PLC vents; FIRE is refused)."""

from __future__ import annotations

import asyncio
from pathlib import Path

from rig.core.bat import BatSpec
from rig.core.tomlfile import dump_toml
from rig.session import scene_with_bat
from rig.simulators.instruments.serve import rig_config, start_twins
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from rig.store import Store
from rig.tui import ConsoleSettings, RigConsole
from rig.tui.modals import ConfirmScreen
from tests.tui.conftest import QUICK, SAMPLE_BAT, answer_prompts, start_run, until
from tests.tui.test_console import SIZE, screen_text


def test_the_console_never_fires_through_the_plc_with_an_interlock_open(tmp_path: Path) -> None:
    world = SimWorld(scene_with_bat(Scene.load("ideal"), BatSpec.load(SAMPLE_BAT)))
    twins = start_twins(world)
    plc = next(t for t in twins if t.KIND == "cannon")
    config = tmp_path / "rig.toml"
    config.write_text(dump_toml(rig_config(world.scene, twins)), encoding="utf-8")
    settings = ConsoleSettings.from_args(
        None, str(config), tmp_path / "records.db", bat=str(SAMPLE_BAT), procedure=str(QUICK)
    )
    settings.poll_s = 0.25

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            await until(pilot, lambda: screen.operator.pending and not screen.fire_block(), "fire-1", 60)
            with world.lock:
                world.set_interlock("door", False)  # the door opens while the shot waits
            await until(pilot, lambda: "door" in screen.fire_block(), "the open door to show", 60)
            assert "door OPEN" in screen_text(app, "#cannon")
            await pilot.press("f")
            assert not isinstance(app.screen, ConfirmScreen)  # no way to fire
            assert world.shots == []
            with world.lock:
                world.set_interlock("door", True)
            await until(pilot, lambda: not screen.fire_block(), "the door to close", 60)
            plc.door_opens_after_arm = True  # now the door opens right after the PLC accepts ARM
            await pilot.press("f")
            await until(pilot, lambda: not screen.running, "the refused shot to stop the run", 60)
            assert world.shots == [] and not world.door  # the PLC vented, the driver refused FIRE
            assert screen.outcome is not None and screen.outcome.status == "interrupted"
            assert "FIRE not sent" in str(screen.outcome.reason)
            plc.door_opens_after_arm = False
            with world.lock:
                world.set_interlock("door", True)
            await pilot.press("r")  # resumed from the console once the door is shut
            await until(pilot, lambda: screen.running, "the resumed run", 60)
            await answer_prompts(pilot, screen, timeout=120)
            assert screen.outcome is not None and screen.outcome.status == "finished"

    try:
        asyncio.run(body())
    finally:
        for twin in twins:
            twin.close()
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        fired = store.entries(run.run_id, kinds=["ShotFired"])
        refused = [e for e in store.entries(run.run_id) if "FIRE not sent" in str(e.payload)]
    assert run.status == "finished"
    assert len(fired) == len(world.shots) == 4  # every launch recorded once, none with the door open
    assert refused, "the refusal after ARM is recorded"
