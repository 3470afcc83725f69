"""Progress bars for long work: rich's, on stderr, and only when stderr is a terminal.

In a pipe, a file or CI nothing is drawn, so logs and captured output stay clean.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class Steps:
    """A bar of `total` steps; `advance()` one step, `note(text)` to change what it says; as a
    timer wrapper, `counted(timer)` advances once per timed solve."""

    def __init__(self, bar: Any = None, task: Any = None) -> None:
        self._bar, self._task = bar, task

    def advance(self, n: float = 1.0) -> None:
        if self._bar is not None:
            self._bar.advance(self._task, n)

    def note(self, text: str) -> None:
        if self._bar is not None:
            self._bar.update(self._task, description=text)

    def counted(self, timer: Any) -> Any:
        """`timer` (a study's stopwatch: called with a solve, has .repeats) advancing this bar."""
        return _Counted(timer, self)


class _Counted:
    """A stopwatch that advances a bar after each solve it times."""

    def __init__(self, timer: Any, bar: Steps) -> None:
        self._timer, self._bar = timer, bar
        self.repeats = timer.repeats

    def __call__(self, solve: Any) -> Any:
        out = self._timer(solve)
        self._bar.advance()
        return out


def shown() -> bool:
    """Whether a bar would be drawn: stderr is a terminal."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


@contextmanager
def steps(total: float | None, what: str) -> Iterator[Steps]:
    """A progress bar on stderr for `total` steps of `what` (None: a count with no end known);
    nothing when stderr is not a terminal."""
    if not shown():
        yield Steps()
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        yield Steps(bar, bar.add_task(what, total=total))
