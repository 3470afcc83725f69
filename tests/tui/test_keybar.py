"""The run screen's key bar (which replaced Textual's Footer there): it offers exactly the keys the
screen allows now, dims the ones it does not, follows the prompts, and a click on an offered key
does what the key does, while a click on a dimmed one does nothing."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from rich.cells import cell_len
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.screen import Screen

from rig.tui import ConsoleSettings, RigConsole
from rig.tui.keybar import KeyBar
from rig.tui.modals import ConfirmScreen
from rig.tui.run import RunScreen
from tests.tui.conftest import start_run, until

SIZE = (100, 30)


def shown(screen: RunScreen) -> tuple[list[str], list[str]]:
    """The screen's own view of its keys: (offered, dimmed) descriptions, one per action."""
    offered: list[str] = []
    dimmed: list[str] = []
    seen: set[str] = set()
    for _, binding, enabled, _ in screen.active_bindings.values():
        if binding.show and binding.action not in seen:
            seen.add(binding.action)
            (offered if enabled else dimmed).append(binding.description)
    return offered, dimmed


def bar_shows(bar: KeyBar, offered: list[str], dimmed: list[str]) -> bool:
    """The bar's text names every key the screen knows, and only the offered ones can be clicked."""
    text = str(bar.render())
    return all(f" {d} " in text for d in offered + dimmed) and len(bar._spans) == len(offered)


def column_of(bar: KeyBar, description: str) -> int:
    """The screen column (cells, not characters) of a key's description in the bar."""
    text = str(bar.render())
    at = text.find(f" {description} ")
    assert at >= 0, f"{description!r} not in the key bar: {text!r}"
    return cell_len(text[: at + 1])


def test_the_key_bar_follows_the_prompts_and_a_click_is_a_key_press(
    make_settings: Callable[..., ConsoleSettings],
) -> None:
    settings = make_settings()
    ring: list[tuple[list[str], list[str]]] = []
    stopped: list[object] = []

    async def body() -> None:
        async with RigConsole(settings).run_test(size=SIZE) as pilot:
            screen = await start_run(pilot)
            bar = screen.query_one(KeyBar)
            op = screen.operator
            await until(pilot, lambda: op.pending is not None and not op.pending.is_fire, "a ring check")
            # the bar shows what the screen offers, with a click region for each offered key only
            await until(
                pilot, lambda: bar_shows(bar, *shown(screen)), "the bar to show the ring check's keys"
            )
            offered, dimmed = shown(screen)
            ring.append((offered, dimmed))
            # a click on the dimmed Fire: nothing happens (no fire, no answer)
            pending = op.pending
            assert "Fire" in dimmed
            assert "f" not in [key for _, _, key in bar._spans]  # a dimmed key has no click region
            await pilot.click(KeyBar, offset=(column_of(bar, "Fire"), 0))
            await pilot.pause()
            assert op.pending is pending and not isinstance(pilot.app.screen, ConfirmScreen)
            # a click on OK answers the ring check as Enter does; the bar then offers the next keys
            await pilot.click(KeyBar, offset=(column_of(bar, "OK"), 0))
            await until(pilot, lambda: op.pending is not pending, "the click's answer")
            await until(pilot, lambda: op.pending is not None and op.pending.is_fire, "the fire prompt")
            await until(pilot, lambda: not screen.fire_block(), "the cannon to be ready")
            await until(pilot, lambda: "Fire" in shown(screen)[0], "Fire to be offered")
            # the bar follows (the screen redraws it when its keys change: on a busy machine, soon after)
            await until(pilot, lambda: any(key == "f" for _, _, key in bar._spans), "the bar to offer Fire")
            assert " Fire " in str(bar.render())
            # a click on Abort asks first, as the a key does
            await pilot.click(KeyBar, offset=(column_of(bar, "Abort"), 0))
            await until(pilot, lambda: isinstance(pilot.app.screen, ConfirmScreen), "the abort question")
            await pilot.press("y")
            await until(pilot, lambda: not screen.running, "the run to stop")
            stopped.append(screen.outcome)

    asyncio.run(body())
    ((offered, dimmed),) = ring
    assert "Abort" in offered and "Fire" in dimmed
    assert stopped and stopped[0] is not None


class Odd(Screen[None]):
    """Keys and names with markup characters and wide (two-cell) characters."""

    BINDINGS = [  # noqa: RUF012
        Binding("left_square_bracket", "hit('open')", "[Open]"),
        Binding("w", "hit('wide')", "全角 name", key_display="キー"),
        Binding("g", "hit('off')", "Off"),
        Binding("v", "hit('after')", "After $x"),
        Binding("backslash", "hit('back')", "Back\\"),
    ]

    def __init__(self) -> None:
        super().__init__()
        self.hits: list[str] = []

    def compose(self) -> ComposeResult:
        yield KeyBar()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        return None if parameters == ("off",) else True  # g is known but off: dimmed

    def action_hit(self, what: str) -> None:
        self.hits.append(what)


class OddApp(App[None]):
    def on_mount(self) -> None:
        self.push_screen(Odd())


def test_the_bar_shows_names_as_written_and_a_click_lands_on_the_key_under_it() -> None:
    async def body() -> None:
        app = OddApp()
        async with app.run_test(size=(100, 5)) as pilot:
            await pilot.pause()
            screen = app.screen
            assert isinstance(screen, Odd)
            bar = screen.query_one(KeyBar)
            text = str(bar.render())
            for shown in (" [ [Open] ", " キー 全角 name ", " g Off ", " v After $x ", " \\ Back\\ "):
                assert shown in text, (shown, text)
            for name, expected in (
                ("After $x", ["after"]),
                ("Off", ["after"]),
                ("全角 name", ["after", "wide"]),
            ):
                await pilot.click(KeyBar, offset=(column_of(bar, name), 0))
                await pilot.pause()
                assert screen.hits == expected, (name, screen.hits)

    asyncio.run(body())
