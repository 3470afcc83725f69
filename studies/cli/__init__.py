"""The `rig-study` command: the studies, apart from the `rig` command (which never imports them).

Errors are as `rig`'s: one line naming the cause, exit status 2, and with --json a JSON error object.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from rig.cli import run_command
from studies.cli import accuracy, population


def build_parser() -> argparse.ArgumentParser:
    """The study commands."""
    parser = argparse.ArgumentParser(
        prog="rig-study", description="Studies of the bat-certification rig's model and populations."
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for part in (accuracy, population):
        part.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `rig-study` console script (and `python -m studies`)."""
    return run_command(build_parser().parse_args(argv), "rig-study")


__all__ = ["build_parser", "main"]
