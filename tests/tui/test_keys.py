"""The operator's keys: the first screen takes a bat path, and a whole BBCOR takes few keys.

Every key goes through `Keys.press`, which counts it; the fires are counted on the record
(ShotFired) and compared with the operator's confirmations (OperatorAnswered fire-N: yes) and
with the fire keys the test pressed, so "fewer keys" can never mean "fires nobody confirmed".
"""

from __future__ import annotations

import asyncio
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest
from textual.containers import VerticalScroll
from textual.pilot import Pilot
from textual.widgets import DataTable, Input, Static

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.store import Store
from rig.tui import ConsoleSettings, RigConsole
from rig.tui.history import HistoryScreen, ReportView
from rig.tui.operator import ConsoleOperator
from rig.tui.run import RunScreen
from rig.tui.setup import SetupScreen
from tests.tui.conftest import QUICK, SAMPLE_BAT, one_key_rig, start_run, until

SIZE = (80, 24)
MAX_KEYS = 40


class Keys:
    """Pilot.press that counts every key."""

    def __init__(self, pilot: Pilot) -> None:
        self.pilot, self.pressed = pilot, []

    async def press(self, *keys: str) -> None:
        self.pressed.extend(keys)
        await self.pilot.press(*keys)


def test_typing_a_bat_path_on_the_first_screen_loads_it(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    async def body() -> None:
        app = RigConsole(make_settings(bat_path=""))
        async with app.run_test(size=SIZE) as pilot:
            setup = app.screen
            assert isinstance(setup, SetupScreen)
            await pilot.pause()
            assert app.focused is setup.query_one("#bat-file", Input)
            path = str(SAMPLE_BAT)
            await pilot.press(*path, "enter")  # one character at a time, as typed
            assert setup.query_one("#bat-file", Input).value == path
            bat = tomllib.loads(SAMPLE_BAT.read_text())["bat"]  # the file itself, not BatSpec
            assert setup.query_one("#bat-id", Input).value == bat["id"]
            assert float(setup.query_one("#bat-length_in", Input).value) == bat["length_in"]
            assert isinstance(app.screen, SetupScreen)  # no hotkey fired on the way
            assert [n.title for n in app._notifications] == []  # no "Cannot start" pop-up
            assert f"bat {bat['id']} loaded" in str(setup.query_one("#status", Static).render())

    asyncio.run(body())


def test_whole_bbcor_in_at_most_40_keys_every_fire_confirmed(
    make_settings: Callable[..., ConsoleSettings], tmp_path: Path
) -> None:
    """On a rig whose lab chose the one key: Enter on a review also passes the ring checks up to the
    next hit, and the record says which answers came with which key (issue 24: not as inspected)."""
    settings = make_settings()
    settings.rigs = (one_key_rig(tmp_path),)
    fire_keys = 0

    async def body() -> list[str]:
        nonlocal fire_keys
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            keys = Keys(pilot)
            await until(pilot, lambda: isinstance(app.screen, SetupScreen) and app.screen.report, "set-up")
            await keys.press("s")
            await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")
            screen = app.screen
            assert isinstance(screen, RunScreen)
            op: ConsoleOperator = screen.operator
            deadline = time.monotonic() + 120
            while screen.running:
                assert time.monotonic() < deadline, "the run did not end in time"
                await until(
                    pilot,
                    lambda: (
                        not screen.running
                        or (op.pending is not None and (not op.pending.is_fire or not screen.fire_block()))
                    ),
                    "a prompt",
                )
                prompt = op.pending
                if not screen.running or prompt is None:
                    continue
                if prompt.is_fire:
                    fire_keys += 1
                    await keys.press("f")
                elif prompt.prompt_id == "edge-location":
                    await keys.press("y")
                else:  # a ring check, a review of a valid shot, the ball: no thought needed
                    await keys.press("enter")
                await until(pilot, lambda p=prompt: op.pending is not p, "the answer to go through")
            assert screen.outcome is not None and screen.outcome.status == "finished"
            return keys.pressed

    pressed = asyncio.run(body())
    print(f"\nkeys from set-up to the verdict: {len(pressed)} ({' '.join(pressed)})")
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        assert run.status == "finished" and run.verdict == "PASS"
        fired = store.entries(run.run_id, kinds=["ShotFired"])
        answered = [e.payload for e in store.entries(run.run_id, kinds=["OperatorAnswered"])]
        confirmed = [p for p in answered if p["prompt_id"].startswith("fire-") and p["answer"]]
        rings = [p for p in answered if p["prompt_id"].startswith("ring-")]
    assert len(fired) == len(confirmed) == fire_keys == 14  # one operator's key per fire, no more
    assert {f"fire-{e.payload['index']}" for e in fired} == {p["prompt_id"] for p in confirmed}
    assert len(rings) == 28 and all(p["answer"] for p in rings)  # before and after every hit
    assert len(pressed) <= MAX_KEYS
    # the first ring check was asked on its own prompt; each later one came with the review of the
    # hit before it (Enter), and the record says so
    # each ring check came with the review of the hit before it (Enter on the review), unless a
    # question that needed thought came between (edge-location): then it was asked; a new ball
    # between does not touch the bat
    review = None
    for p in answered:
        kind = p["prompt_id"].rpartition("-")[0]
        if kind == "review":
            review = p["prompt_id"]
        elif kind.startswith("ring"):
            assert (p["given"], p.get("with_prompt")) == (("with", review) if review else ("asked", None)), p
        elif p["prompt_id"] != "ball":  # a fire, or a question that needed thought
            review = None
    assert rings[0]["given"] == "asked" and sum(p["given"] == "with" for p in rings) >= 24
    reviews = [p for p in answered if p["prompt_id"].startswith("review-")]
    assert len(reviews) == 14 and all(p["given"] == "asked" for p in reviews)


def test_history_shows_the_certificate_without_drawing_figures(
    make_settings: Callable[..., ConsoleSettings], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The History screen renders the certificate's Markdown and never a PNG (that took seconds)."""
    import rig.report.cert_plots as plots

    drawn: list[object] = []
    monkeypatch.setattr(plots, "write_figures", lambda *a, **k: drawn.append(a) or {})
    monkeypatch.chdir(tmp_path)  # any figure folder would land here
    settings = make_settings()
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(settings.db) as store:
        run_id = certify(store, Procedure.load(QUICK), bat, sim_config("ideal", bat=bat)).run_id

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: isinstance(app.screen, SetupScreen) and app.screen.report, "set-up")
            await pilot.press("h")
            await until(pilot, lambda: isinstance(app.screen, HistoryScreen), "the history")
            report = app.screen.query_one("#report-text", ReportView)
            await until(pilot, lambda: report.source.startswith("# Bat performance certificate"), "it")
            return report.source

    source = asyncio.run(body())
    assert drawn == [] and list(tmp_path.rglob("*.png")) == []
    assert run_id in source and "Quick BBCOR (UI tests)" in source and "![" not in source


def test_the_history_report_scrolls_with_pgdn_from_the_run_list_and_help_says_so(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    """The report needed Tab then PgDn, and neither the footer nor help said so."""
    settings = make_settings()
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(settings.db) as store:
        certify(store, Procedure.load(QUICK), bat, sim_config("ideal", bat=bat))

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: isinstance(app.screen, SetupScreen) and app.screen.report, "set-up")
            await pilot.press("h")
            await until(pilot, lambda: isinstance(app.screen, HistoryScreen), "the history")
            history = app.screen
            report = history.query_one("#report-text", ReportView)
            await until(pilot, lambda: report.source.startswith("# Bat performance certificate"), "it")
            await pilot.pause()
            table = history.query_one("#runs", DataTable)
            assert table.has_focus and "pagedown" in app.active_bindings  # offered in the footer
            scroll = history.query_one("#report", VerticalScroll)
            await pilot.press("pagedown")
            await until(pilot, lambda: scroll.scroll_y > 0, "the report to scroll")
            assert table.has_focus and table.cursor_row == 0
            await pilot.press("pageup")
            await until(pilot, lambda: scroll.scroll_y == 0, "the report to scroll back")
            await pilot.press("question_mark")
            help_text = str(app.screen.query_one("#help", Static).render())
            assert "PgDn" in help_text and "report" in help_text.split("PgDn")[1][:40]

    asyncio.run(body())


def test_the_set_up_screen_reads_the_devices_once(
    make_settings: Callable[..., ConsoleSettings], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The read starts after the first paint; the rig selector's first event must not start another
    (two reads at once: the second finds the ports busy)."""
    import rig.tui.setup as setup_module

    calls: list[str] = []
    real = setup_module.read_devices
    monkeypatch.setattr(
        setup_module, "read_devices", lambda config, lock: calls.append("read") or real(config, lock)
    )

    async def body() -> None:
        app = RigConsole(make_settings())
        async with app.run_test(size=SIZE) as pilot:
            setup = app.screen
            assert isinstance(setup, SetupScreen)
            await until(pilot, lambda: setup.report is not None, "the device check")
            await until(pilot, lambda: all(w.is_finished for w in app.workers), "idle")
            assert setup.report is not None and setup.report.errors == ()
            await pilot.press("r")  # asked again: read again
            await until(pilot, lambda: len(calls) == 2 and setup.report is not None, "the second read")

    asyncio.run(body())
    assert calls == ["read", "read"]


def test_by_default_each_ring_check_is_asked_on_its_own_prompt(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    """Issue 24: Enter on a review accepts the shot only; the ring checks after it and before the next
    hit are each asked, and recorded as answered on their own prompts."""
    settings = make_settings()
    asked: list[str] = []

    async def body() -> None:
        async with RigConsole(settings).run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            op: ConsoleOperator = screen.operator
            while "ring-before-2" not in asked:
                await until(
                    pilot,
                    lambda: (
                        op.pending is not None
                        and op.pending.prompt_id not in asked
                        and (not op.pending.is_fire or not screen.fire_block())
                    ),
                    "the next prompt",
                )
                prompt = op.pending
                assert prompt is not None
                asked.append(prompt.prompt_id)
                if prompt.prompt_id == "ring-before-2":
                    break
                await pilot.press("f" if prompt.is_fire else "enter")
                await until(pilot, lambda p=prompt: op.pending is not p, "the answer to go through")
            screen.stop("test over")
            await until(pilot, lambda: not screen.running, "the run to stop")

    asyncio.run(body())
    assert asked == ["ring-before-1", "fire-1", "review-1", "ring-after-1", "ring-before-2"]
    with Store.open(settings.db, create=False) as store:
        (run,) = store.runs()
        answered = [e.payload for e in store.entries(run.run_id, kinds=["OperatorAnswered"])]
    rings = [p for p in answered if not p["prompt_id"].startswith("fire-")]
    assert [(p["prompt_id"], p["answer"], p["given"]) for p in rings] == [
        ("ring-before-1", True, "asked"),
        ("review-1", True, "asked"),
        ("ring-after-1", True, "asked"),
    ]


def test_a_withdrawn_fail_and_a_pause_are_not_passed_by_habit(
    make_settings: Callable[..., ConsoleSettings], tmp_path: Path
) -> None:
    """Review of issue 14: n, Enter (withdraws the fail), Enter recorded the ring check as passed;
    and ring checks passed ahead by Enter on a review survived a pause, when the bat may be handled.
    Now the withdrawn check needs y or n, and a pause drops answers given ahead (a rig whose lab
    chose the one key: without it nothing is answered ahead)."""
    settings = make_settings()
    settings.rigs = (one_key_rig(tmp_path),)

    async def body() -> None:
        app = RigConsole(settings)
        async with app.run_test(size=SIZE) as pilot:
            await until(pilot, lambda: isinstance(app.screen, SetupScreen) and app.screen.report, "set-up")
            await pilot.press("s")
            await until(pilot, lambda: isinstance(app.screen, RunScreen), "the run screen")
            screen = app.screen
            assert isinstance(screen, RunScreen)
            op: ConsoleOperator = screen.operator
            await until(pilot, lambda: op.pending is not None, "the first ring check")
            first = op.pending
            assert first is not None and first.prompt_id.startswith("ring-before-")
            await pilot.press("n")  # fail ... then withdraw it (the dialog's focus is on No)
            await until(pilot, lambda: not isinstance(app.screen, RunScreen), "the confirmation")
            await pilot.press("enter")
            await until(pilot, lambda: app.screen is screen, "back to the run")
            await pilot.press("enter")  # habit: this must not pass what was just failed
            await pilot.pause(0.3)
            assert op.pending is first, "Enter answered a ring check whose fail was withdrawn"
            await pilot.press("y")  # an explicit pass goes through
            await until(pilot, lambda: op.pending is not first, "the answer")
            # the first shot: fire it, then accept the review with Enter (passes the next checks ahead)
            await until(
                pilot,
                lambda: op.pending is not None and op.pending.is_fire and not screen.fire_block(),
                "fire",
            )
            await pilot.press("f")
            await until(
                pilot, lambda: op.pending is not None and op.pending.prompt_id.startswith("review-"), "review"
            )
            await pilot.press("p")  # pause first: the bat may be handled now
            await pilot.press("enter")
            await pilot.press("p")  # go on
            await until(
                pilot,
                lambda: op.pending is not None and op.pending.prompt_id.startswith("ring-after-"),
                "asked",
            )  # asked again, not answered ahead
            screen.stop("test over")

    asyncio.run(body())
