"""The console driven headless by Textual's Pilot on the simulated rig, at 80x24."""

from __future__ import annotations

import asyncio
import re
from collections.abc import Callable
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

import pytest
from textual.widgets import DataTable, Input, Static

from rig.cli import main
from rig.simulators.urlhandler import get_world
from rig.store import Store
from rig.tui import ConsoleSettings, RigChoice, RigConsole
from rig.tui.history import HistoryScreen
from rig.tui.modals import ConfirmScreen, HelpScreen
from rig.tui.rigs import LeftOpen
from rig.tui.run import RunScreen
from rig.tui.setup import SetupScreen
from tests.tui.conftest import QUICK, SAMPLE_BAT, answer_prompts, start_run, until

SIZE = (80, 24)


def screen_text(app: RigConsole, selector: str) -> str:
    """The plain text a Static shows."""
    return str(app.screen.query_one(selector, Static).render())


def test_whole_certification_to_the_verdict(make_settings: Callable[..., ConsoleSettings]) -> None:
    settings = make_settings()

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            await answer_prompts(pilot, screen)
            assert screen.outcome is not None and screen.outcome.status == "finished"
            # U now holds the ball's terms (assumed defaults without a lot): its digits, not a fixed value
            assert re.search(
                r"PASS  bbcor 0\.4638 ± 0\.\d{4} \(k=2\), limit 0\.5: pass", screen_text(app, "#message")
            )
            assert "Run finished" in screen_text(app, "#prompt")
            assert "0.4638" in screen_text(app, "#progress") and "6/6 valid" in screen_text(app, "#progress")
            await pilot.press("h")  # the history lists it
            await until(pilot, lambda: isinstance(app.screen, HistoryScreen), "the history")
            assert app.screen.runs[0].verdict == "PASS"

    asyncio.run(body())
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "finished" and run.verdict == "PASS"
        answered = store.entries(run.run_id, kinds=["OperatorAnswered"])
        fires = [e.payload for e in answered if e.payload["prompt_id"].startswith("fire-")]
        # 6 scan + 2 extensions towards the handle (the ideal bat peaks beyond 7.5 in) + 6 hits
        assert len(fires) == 14 and all(p["answer"] and p["who"].startswith("console") for p in fires)


def test_open_interlock_disables_fire(make_settings: Callable[..., ConsoleSettings]) -> None:
    settings = make_settings(procedure=str(QUICK))

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            pending = screen.operator
            await until(pilot, lambda: pending.pending and not screen.fire_block(), "fire-1 to be armable")
            assert screen.check_action("fire", ()) is True
            rig = parse_qs(urlsplit(screen.job.config.ports.cannon).query)["rig"][0]
            get_world(rig).set_interlock("door", False)  # the door opens while the shot waits
            await until(pilot, lambda: "door" in screen.fire_block(), "the open door to show")
            assert screen.check_action("fire", ()) is None  # shown, disabled
            assert "FIRE DISABLED: interlock open: door" in screen_text(app, "#prompt")
            assert "door OPEN" in screen_text(app, "#cannon")
            await pilot.press("f")
            assert not isinstance(app.screen, ConfirmScreen)  # no way to fire
            assert pending.pending is not None and pending.pending.prompt_id == "fire-1"
            get_world(rig).set_interlock("door", True)
            await until(pilot, lambda: not screen.fire_block(), "the door to close")
            await pilot.press("p")  # paused: no firing either
            assert screen.fire_block() == "paused" and "PAUSED p goes on" in screen_text(app, "#prompt")
            await pilot.press("f", "enter", "y")  # neither the fire key nor the answer keys fire it
            assert pending.pending is not None and pending.pending.prompt_id == "fire-1"
            await pilot.press("p")
            assert not screen.fire_block()
            await pilot.press("a")  # abort, confirmed: the run stops and stays resumable
            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the abort confirmation")
            await pilot.press("y")
            await until(pilot, lambda: not screen.running, "the run to stop")
            assert screen.outcome is not None and screen.outcome.status == "interrupted"
            assert "r resumes" in screen_text(app, "#prompt")
            await pilot.press("r")  # resume it to the end
            await answer_prompts(pilot, screen)
            assert screen.outcome is not None and screen.outcome.status == "finished"

    asyncio.run(body())
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "finished"
        assert len(store.entries(run.run_id, kinds=["ShotFired"])) == 4


def test_a_failed_ring_check_asks_first_then_fails_the_bat(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    settings = make_settings()

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            await until(pilot, lambda: screen.operator.pending is not None, "the ring check")
            await pilot.press("n")
            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the question")
            await pilot.press("n")  # not really: the prompt still waits
            assert screen.operator.pending is not None and screen.running
            await pilot.press("n")
            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the question")
            await pilot.press("y")
            await until(pilot, lambda: not screen.running, "the run to end")
            assert "FAIL  ring check failed at shot 1" in screen_text(app, "#message")

    asyncio.run(body())
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "finished" and run.verdict == "FAIL"


def test_device_faults_show_and_the_console_keeps_running(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    """The faulty scene misfires, drops replies and unplugs the gates: shown, never a crash."""
    settings = make_settings(scene="faulty", procedure=str(QUICK))

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            await answer_prompts(pilot, screen)
            assert screen.outcome is not None and screen.outcome.status == "interrupted"
            assert "unplugged" in screen_text(app, "#message")
            assert "Interrupted" in screen_text(app, "#prompt")
            log = "\n".join(screen.live.log)
            assert "shot 2 lost" in log and "MISFIRE" in log
            titles = [n.title for n in app._notifications]  # earlier ones may have timed out
            assert "Run interrupted (resumable)" in titles
            await pilot.press("question_mark")  # still responsive
            await until(pilot, lambda: isinstance(app.screen, HelpScreen), "the help")
            await pilot.press("escape")
            for _ in range(4):  # resume after each fault until the verdict
                if screen.outcome is not None and screen.outcome.status == "finished":
                    break
                await pilot.press("r")
                await answer_prompts(pilot, screen)
            assert screen.outcome is not None and screen.outcome.status == "finished"
            assert screen.live.verdict is not None
            await pilot.press("b")
            await until(pilot, lambda: isinstance(app.screen, SetupScreen), "back to set-up")

    asyncio.run(body())
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "finished" and store.verify().ok
        assert len(store.entries(run.run_id, kinds=["RunResumed"])) >= 1


def test_a_port_that_does_not_open_is_a_message(tmp_path: Path) -> None:
    rig = tmp_path / "rig.toml"
    ports = {dev: f"/dev/no-such-{dev}" for dev in ("cannon", "gates", "clamp")}
    rig.write_text("[ports]\n" + "".join(f'{dev} = "{url}"\n' for dev, url in ports.items()))

    settings = ConsoleSettings.from_args(None, str(rig), tmp_path / "r.db", bat=str(SAMPLE_BAT))

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            setup = app.screen
            assert isinstance(setup, SetupScreen)
            await until(pilot, lambda: setup.report is not None, "the device check")
            assert "no-such-cannon" in screen_text(app, "#devices")
            screen = await start_run(pilot)
            await until(pilot, lambda: not screen.running, "the run to fail")
            message = screen_text(app, "#message")  # refused before the run: nothing to resume
            assert "the devices could not be opened" in message and "no run was started" in message
            assert "cannon: cannot open '/dev/no-such-cannon'" in message
            assert screen.check_action("resume", ()) is True  # r tries again (a new run) once the cable is in
            await pilot.press("b")
            await until(pilot, lambda: isinstance(app.screen, SetupScreen), "back to set-up")

    asyncio.run(body())
    with Store.open(settings.db) as store:
        assert store.runs() == []


def test_help_overlay_and_quit(make_settings: Callable[..., ConsoleSettings]) -> None:
    async def body() -> None:
        app = RigConsole(make_settings())
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("question_mark")
            await until(pilot, lambda: isinstance(app.screen, HelpScreen), "the help")
            assert "fire the waiting shot" in str(app.screen.query_one("#help", Static).render())
            await pilot.press("escape")
            await until(pilot, lambda: isinstance(app.screen, SetupScreen), "the help to close")
            await pilot.press("q")
            await until(pilot, lambda: not app.is_running, "the app to quit")

    asyncio.run(body())


def test_quit_during_a_run_asks_and_leaves_it_resumable(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    settings = make_settings()

    async def body() -> RigConsole:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            await until(pilot, lambda: screen.operator.pending is not None, "the first prompt")
            await pilot.press("q")
            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the quit question")
            await pilot.press("n")  # stay
            assert app.is_running and screen.running
            await pilot.press("q")
            await until(pilot, lambda: isinstance(app.screen, ConfirmScreen), "the quit question")
            await pilot.press("y")
            await until(pilot, lambda: not app.is_running, "the app to quit")
        return app

    quit_app = asyncio.run(body())
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "running"  # not finished: resumable
        assert store.entries(run.run_id, kinds=["RunInterrupted"])
    # the console knows the run it leaves interrupted, so that `rig tui` can say so (and exit 3)
    assert quit_app.left_open == [
        LeftOpen(run.run_id, "the operator quit the console", RigChoice("sim", "ideal"))
    ]

    async def resume_from_history() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: app.screen.query("#devices"), "the set-up screen")
            await pilot.press("h")
            await until(pilot, lambda: isinstance(app.screen, HistoryScreen), "the history")
            table = app.screen.query_one("#runs", DataTable)
            # as `rig runs` shows it (the review of issue 14 found 'running' here)
            assert str(table.get_row_at(0)[4]) == "interrupted"
            await pilot.press("r")
            await until(pilot, lambda: isinstance(app.screen, RunScreen), "the resumed run")
            screen = app.screen
            assert isinstance(screen, RunScreen) and screen.job.run_id == run.run_id
            await until(pilot, lambda: screen.operator.pending is not None, "its next prompt")
            assert any(line.startswith("resumed after") for line in screen.live.log)

    asyncio.run(resume_from_history())


def test_bat_form_checks_its_values(make_settings: Callable[..., ConsoleSettings]) -> None:
    async def body() -> None:
        app = RigConsole(make_settings(bat_path=""))
        async with app.run_test(size=SIZE) as pilot:
            setup = app.screen
            assert isinstance(setup, SetupScreen)
            setup.query_one("#bat-id", Input).value = "FORM-BAT"
            setup.query_one("#bat-length_in", Input).value = "33"
            setup.query_one("#bat-weight_oz", Input).value = "300"  # a typo
            await pilot.press("escape", "s")  # the bat file field has the keys until Esc
            assert "weight_oz" in str(setup.query_one("#status", Static).render())
            assert isinstance(app.screen, SetupScreen)
            setup.query_one("#bat-weight_oz", Input).value = "30"
            setup.query_one("#bat-balance_point_in", Input).value = "22"
            bat = setup.bat_from_form()
            assert bat.id == "FORM-BAT" and bat.weight_oz == 30.0 and bat.hoop_hz is None

    asyncio.run(body())


def test_rig_choices_from_the_command_line(tmp_path: Path) -> None:
    sim = ConsoleSettings.from_args("lab", None, tmp_path / "r.db")
    assert [r.ref for r in sim.rigs] == ["lab", "ideal", "faulty"]
    real = ConsoleSettings.from_args(None, "rig.toml", tmp_path / "r.db")
    assert real.rigs == (RigChoice("config", "rig.toml"),)


def test_rig_tui_quit_mid_run_says_how_to_resume_and_exits_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """As `rig certify` does for an interrupted run: exit 3 and the resume command, one line a run."""
    db = tmp_path / "r.db"

    def quit_mid_run(app: RigConsole) -> None:
        app.left_open_runs["abc123"] = LeftOpen(
            "abc123", "the operator quit the console", RigChoice("sim", "lab")
        )

    monkeypatch.setattr(RigConsole, "run", quit_mid_run)
    assert main(["tui", "--sim", "lab", "--db", str(db)]) == 3
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("rig: run abc123 interrupted: the operator quit the console; resume with: ")
    assert f"rig certify --resume abc123 --sim lab --db {db}" in line and "rig tui" in line
    monkeypatch.setattr(RigConsole, "run", lambda app: None)  # nothing left open: exit 0, no word
    assert main(["tui", "--sim", "lab", "--db", str(db)]) == 0 and capsys.readouterr().err == ""


def test_the_title_line_docs_tui_quotes_is_what_sim_lab_shows(tmp_path: Path) -> None:
    """docs/tui.md quoted `SIMULATED: ideal`, which `rig tui --sim lab` (the README's) never shows."""
    from rig.core.bat import BatSpec
    from rig.protocols.procedure import Procedure
    from rig.tui.rigs import RunJob

    settings = ConsoleSettings.from_args("lab", None, tmp_path / "r.db", bat=str(SAMPLE_BAT))
    bat, choice = BatSpec.load(SAMPLE_BAT), settings.rigs[0]
    job = RunJob(Procedure.load("bbcor"), bat, choice.config(bat), choice.label, rig=choice)
    title = RunScreen(settings, job)._title()
    docs = " ".join((Path(__file__).resolve().parents[2] / "docs" / "tui.md").read_text().split())
    assert f"`{title}` for `rig tui --sim lab` with the sample bat" in docs


def test_the_operator_named_on_the_setup_screen_is_recorded_as_who_performed_the_test(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    settings = make_settings(procedure=str(QUICK))

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: app.screen.query("#devices"), "the set-up screen")
            app.screen.query_one("#operator", Input).value = "  C. Operator "
            app.screen.query_one("#start").focus()
            screen = await start_run(pilot)
            await answer_prompts(pilot, screen)

    asyncio.run(body())
    from rig.report.record import run_record

    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        record = run_record(store, run.run_id)
    assert record["tested_by"]["name"] == "C. Operator"  # as typed, stripped
    assert record["tested_by"]["answered_by"].startswith("console")
