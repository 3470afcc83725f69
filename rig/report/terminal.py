"""Rich consoles for the command line: rich's own on a terminal; sent to a pipe or a file, plain
(no colour) and never wrapped, so each line stays whole with its indent."""

from __future__ import annotations

from rich.console import Console

PIPED_WIDTH = 400  # columns of output that is not a terminal: no table column is cut


def console(stderr: bool = False, highlight: bool = True) -> Console:
    """A console for stdout (or stderr): on a terminal as rich sets it up; otherwise no colour, a
    table as wide as it needs, and text printed line for line as written (no soft wrapping)."""
    out = Console(stderr=stderr, highlight=highlight)
    if out.is_terminal:
        return out
    return Console(stderr=stderr, width=PIPED_WIDTH, no_color=True, highlight=False, soft_wrap=True)
