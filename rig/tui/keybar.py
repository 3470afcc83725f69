"""A one-line bar of the keys a screen offers now, for a screen whose keys change often.

Textual's Footer rebuilds a widget per key whenever the screen's bindings change, and each rebuild
restyles and lays out the screen: on the run screen, whose keys change with every prompt, that was
half the console's work during a certification. This bar shows the same keys (the bindings shown,
in the same order, one per action, the disabled ones dimmed) as one line of text, redrawn in place.
A click on an offered key presses it, as on the Footer.
"""

from __future__ import annotations

from rich.cells import cell_len
from textual import events
from textual.content import Content
from textual.screen import Screen
from textual.widgets import Static


class KeyBar(Static):
    """The screen's active bindings as one line; `show_keys` redraws it."""

    DEFAULT_CSS = """
    KeyBar {
        dock: bottom;
        height: 1;
        width: 1fr;
        text-wrap: nowrap;
        text-overflow: clip;
        background: $footer-background;
        color: $footer-description-foreground;
    }
    """

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._shown: list[tuple[str, str]] = []
        self._spans: list[tuple[int, int, str]] = []  # (first column, end column, key) of each offered key

    def on_mount(self) -> None:
        self.screen.bindings_updated_signal.subscribe(self, self._bindings_changed)
        self.show_keys()

    def on_unmount(self) -> None:
        self.screen.bindings_updated_signal.unsubscribe(self)

    def _bindings_changed(self, screen: Screen[object]) -> None:
        if self.is_attached and screen is self.screen:
            self.show_keys()

    def show_keys(self) -> None:
        """Redraw from the screen's active bindings (only when they changed)."""
        parts: list[tuple[str, str]] = []
        spans: list[tuple[int, int, str]] = []
        seen: set[str] = set()
        column = 0  # in screen cells: a key or name may hold wide characters
        for _, binding, enabled, _tooltip in self.screen.active_bindings.values():
            if not binding.show or binding.action in seen:
                continue
            seen.add(binding.action)
            key = f" {self.app.get_key_display(binding)} "
            name = f"{binding.description} "
            dim = "" if enabled else " dim"
            parts += [(key, f"b $footer-key-foreground{dim}"), (name, dim.strip())]
            width = cell_len(key) + cell_len(name)
            if enabled:
                spans.append((column, column + width, binding.key))
            column += width
        self._spans = spans
        if parts != self._shown:
            self._shown = parts
            self.update(Content.assemble(*parts), layout=False)  # one line, always

    def on_click(self, event: events.Click) -> None:
        for first, end, key in self._spans:
            if first <= event.x < end:
                self.app.simulate_key(key)  # through the bindings and check_action, as a key press
                return
