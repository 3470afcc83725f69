"""Progress bars for long work: rich's, on stderr, and only when stderr is a terminal.

In a pipe, a file or CI nothing is drawn, so logs and captured output stay clean.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class Steps:
    """A bar of `total` steps; `advance()` one step, `note(text)` to change what it says."""

    def __init__(self, bar: Any = None, task: Any = None) -> None:
        self._bar, self._task = bar, task

    def advance(self, n: float = 1.0) -> None:
        if self._bar is not None:
            self._bar.advance(self._task, n)

    def note(self, text: str) -> None:
        if self._bar is not None:
            self._bar.update(self._task, description=text)


def shown() -> bool:
    """Whether a bar would be drawn: stderr is a terminal."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


@contextmanager
def steps(total: float, what: str) -> Iterator[Steps]:
    """A progress bar on stderr for `total` steps of `what`; nothing when stderr is not a terminal."""
    if not shown():
        yield Steps()
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        yield Steps(bar, bar.add_task(what, total=total))
