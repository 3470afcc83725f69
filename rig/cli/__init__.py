"""The `rig` command line: a thin client over the controller's functions.

Every command has --help. Errors print one line naming the cause and exit with status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from rig.cli import export, keys, modal, model, records, rig_cmds, sync
from rig.core.errors import ParameterError, RigError

Handler = Callable[[argparse.Namespace], int]


def build_parser() -> argparse.ArgumentParser:
    """The whole command tree."""
    parser = argparse.ArgumentParser(prog="rig", description="Bat-certification rig controller.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for part in (model, rig_cmds, records, export, sync, modal, keys):
        part.add_parsers(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `rig` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler = args.handler
    try:
        return handler(args)
    except ParameterError as exc:
        print(f"rig: invalid parameter: {exc}", file=sys.stderr)
    except RigError as exc:
        print(f"rig: {exc}", file=sys.stderr)
    except KeyboardInterrupt:
        return 130
    except OSError as exc:
        print(f"rig: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), file=sys.stderr)
    return 2


__all__ = ["build_parser", "main"]
