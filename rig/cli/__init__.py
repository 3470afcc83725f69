"""The `rig` command line: a thin client over the controller's functions.

Every command has --help. Errors print one line naming the cause and exit with status 2; with
--json, a JSON error object ({"error": {"message", "exit_status"}}) goes to stdout as well.
"""

from __future__ import annotations

import argparse
import json
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
        message = f"invalid parameter: {exc}"
    except RigError as exc:
        message = str(exc)
    except KeyboardInterrupt:
        return 130
    except OSError as exc:
        message = f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": ")
    print(f"rig: {message}", file=sys.stderr)
    if getattr(args, "json", False):  # a program reading the JSON learns of the error too
        json.dump({"error": {"message": message, "exit_status": 2}}, sys.stdout)
        sys.stdout.write("\n")
    return 2


__all__ = ["build_parser", "main"]
