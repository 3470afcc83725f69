"""The `rig` command line: a thin client over the controller's functions.

Every command has --help. Errors print one line naming the cause and exit with status 2; with
--json, a JSON error object ({"error": {"message", "exit_status", "kind"[, "code"]}}) goes to
stdout as well.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence

from rig.cli import (
    balls,
    check,
    compare,
    equipment,
    export,
    keys,
    modal,
    model,
    records,
    rig_cmds,
    screen,
    sync,
)
from rig.core.dbpath import DB_ENV, DEFAULT_DB_NAME
from rig.core.errors import ParameterError, RigError

Handler = Callable[[argparse.Namespace], int]


def build_parser() -> argparse.ArgumentParser:
    """The whole command tree."""
    parser = argparse.ArgumentParser(
        prog="rig",
        description="Bat-certification rig controller.",
        epilog=(
            f"Records go to {DEFAULT_DB_NAME} in the working directory unless --db names another store"
            f" (a file or a postgresql:// URL) or the environment variable {DB_ENV} does."
        ),
    )
    parser.add_argument("--version", action=_Version, nargs=0, help="print the version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for part in (
        records,
        check,
        keys,
        export,
        compare,
        equipment,
        sync,
        balls,
        rig_cmds,
        model,
        modal,
        screen,
    ):  # task order in --help
        part.add_parsers(sub)
    return parser


class _Version(argparse.Action):
    """--version: looks the version up only when asked (importlib.metadata costs ~20 ms)."""

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> None:
        print(f"rig {_version()}")
        parser.exit()


def _version() -> str:
    """The installed package's version (the source's when not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("bat-rig")
    except PackageNotFoundError:
        from rig.core.version import __version__

        return __version__


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the `rig` console script."""
    return run_command(build_parser().parse_args(argv))


def run_command(args: argparse.Namespace, prog: str = "rig") -> int:
    """Run a parsed command's handler; an error is one line `PROG: message` on stderr, exit 2."""
    handler: Handler = args.handler
    error: Exception
    try:
        return handler(args)
    except ParameterError as exc:
        message, error = f"invalid parameter: {exc}", exc
    except RigError as exc:
        message, error = str(exc), exc
    except KeyboardInterrupt:
        return 130
    except OSError as exc:
        message, error = f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": "), exc
    print(f"{prog}: {message}", file=sys.stderr)
    if getattr(args, "json", False):  # a program reading the JSON learns of the error too
        json.dump({"error": _error_object(message, error)}, sys.stdout)
        sys.stdout.write("\n")
    return 2


def _error_object(message: str, error: Exception) -> dict[str, object]:
    """The JSON error: the message, the exit status, the error's kind and, for a modal
    diagnosis, its stable code (docs/modal.md)."""
    out: dict[str, object] = {"message": message, "exit_status": 2, "kind": type(error).__name__}
    code = getattr(type(error), "code", None)
    if isinstance(code, str):
        out["code"] = code
    return out


__all__ = ["build_parser", "main", "run_command"]
