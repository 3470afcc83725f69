"""What the commands share: output, argument types, rig selection, the record store."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rig.core.errors import ConfigError


def param_override(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name.strip()}: {value!r} is not a number") from None


def emit(args: argparse.Namespace, payload: dict[str, Any], title: str) -> None:
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title, show_header=True)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for key, value in payload.items():
        if isinstance(value, list):
            value = f"[{len(value)} values]"
        elif isinstance(value, float):
            value = f"{value:.6g}"
        table.add_row(key, str(value))
    Console().print(table)


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


Bounds = dict[str, tuple[str, float, float, str]]  # flag dest -> (name, low, high, unit)


def check_flags(args: argparse.Namespace, bounds: Bounds) -> None:
    """ParameterError naming the first flag outside its physical range (a list flag: each value)."""
    from rig.core.errors import ParameterError

    for dest, (name, low, high, unit) in bounds.items():
        value = getattr(args, dest, None)
        for v in value if isinstance(value, list) else [value]:
            if v is not None and not low <= v <= high:  # also refuses nan
                raise ParameterError(name, v, f"must lie within {low:g}-{high:g} {unit}".rstrip())


def rig_config(args: argparse.Namespace, bat: Any = None) -> Any:
    """The rig config from --sim, --config or (where the command has them) the three port URLs.

    With `bat`, a simulated bat takes the bat file's properties as its true ones.
    """
    from rig.core.config import RigConfig

    if args.sim is not None:
        from rig.session import sim_config

        return sim_config(args.sim, bat=bat)
    if args.config:
        return RigConfig.load(args.config)
    if not hasattr(args, "cannon"):
        raise ConfigError("give --sim [SCENE] or --config RIG.toml", source="command line")
    ports = {"cannon": args.cannon, "gates": args.gates, "clamp": args.clamp}
    missing = [f"--{k}" for k, v in ports.items() if not v]
    if missing:
        raise ConfigError(f"give --sim [SCENE], --config RIG.toml, or all of {', '.join(missing)}")
    return RigConfig.from_dict({"ports": ports}, source="command line")


def default_db() -> Path:
    """Where records go when no --db is given."""
    from rig.certification import default_db as where

    return where()


def shown_db(db: object) -> str:
    """A --db value as it may be printed: a database URL's password masked."""
    from rig.store import safe_url

    return safe_url(str(db))


def open_db(args: argparse.Namespace) -> Any:
    from rig.store import Store

    return Store.open(args.db or default_db(), create=getattr(args, "create_db", False))


def resolve_run(store: Any, text: str) -> str:
    """A run id from a full id, a unique prefix, or 'last' (the newest run)."""
    if text == "last":
        runs = store.runs()
        if not runs:
            raise ConfigError("the record store has no runs yet", source="run")
        return runs[-1].run_id
    matches = [r.run_id for r in store.runs() if r.run_id.startswith(text)]
    if len(matches) == 1:
        return matches[0]
    return store.run(text).run_id  # raises a clear error for unknown or ambiguous ids


def add_rig_options(p: argparse.ArgumentParser) -> None:
    """--sim [SCENE] or --config RIG.toml, one of them."""
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--sim",
        nargs="?",
        const="ideal",
        metavar="SCENE",
        help="simulated rig: ideal (default), lab, faulty or a scene TOML file",
    )
    where.add_argument("--config", metavar="RIG.toml", help="rig configuration file")
