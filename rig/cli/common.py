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


def add_overrides(parser: argparse.ArgumentParser, help_text: str) -> None:
    """--set NAME=VALUE (repeatable): model constants to override, collected in `overrides`."""
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="NAME=VALUE",
        type=param_override,
        action="append",
        default=[],
        help=help_text,
    )


def console(stderr: bool = False) -> Any:
    """A rich console: on a terminal rich's own; piped or redirected, no colour, no wrapping and
    wide enough that no table column is cut (rig.report.terminal)."""
    from rig.report.terminal import console as terminal_console

    return terminal_console(stderr)


def new_table(**options: Any) -> Any:
    """A rich table whose columns fold rather than cut; plain ASCII rules when stdout is not a
    terminal (no box-drawing characters in a file or a pipe)."""
    from rich import box
    from rich.table import Table

    if not console().is_terminal:
        options.setdefault("box", box.ASCII)
    return Table(**options)


def add_columns(table: Any, *names: str, justify: str = "left") -> None:
    """Columns that never cut a value: a long one folds onto a second line."""
    for name in names:
        table.add_column(name, justify=justify, overflow="fold")


def add_plain_row(table: Any, *cells: str) -> None:
    """A row whose cells are shown as written: brackets in a bat id or an item's name are not markup."""
    from rich.text import Text

    table.add_row(*(Text(cell) for cell in cells))


def _cell(value: Any) -> str:
    """A value as a table cell: numbers to 6 significant digits, no Python reprs."""
    if isinstance(value, bool) or value is None:
        return {True: "yes", False: "no", None: "-"}[value]
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list | tuple):
        if not value:
            return "-"
        return f"[{len(value)} values]" if len(value) > 6 else ", ".join(_cell(v) for v in value)
    return str(value)


def flat_rows(payload: dict[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    """(name, text) rows of a payload; a nested mapping becomes 'outer.inner' rows, not a dict repr."""
    rows: list[tuple[str, str]] = []
    for key, value in payload.items():
        if isinstance(value, dict):
            rows += flat_rows(value, f"{prefix}{key}.")
        else:
            rows.append((f"{prefix}{key}", _cell(value)))
    return rows


def emit(args: argparse.Namespace, payload: dict[str, Any], title: str) -> None:
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return
    table = new_table(title=title, show_header=True)
    add_columns(table, "quantity")
    add_columns(table, "value", justify="right")
    for key, value in flat_rows(payload):
        table.add_row(key, value)
    console().print(table)


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


def rig_config(
    args: argparse.Namespace, bat: Any = None, session: str | None = None, procedure: Any = None
) -> Any:
    """The rig config from --sim, --config or (where the command has them) the three port URLs.

    With `bat`, a simulated bat takes the bat file's properties as its true ones; `session` names
    this run of a simulated lab (its own noise, rig.session.sim_config); `procedure`: a simulated
    lab loads the balls it names (its ball class) and aims as low as its speed.
    """
    from rig.core.config import RigConfig

    if args.sim is not None:
        from rig.session import sim_config

        ball_class = None if procedure is None else procedure.ball.ball_class
        speed = None if procedure is None else procedure.target_speed_m_s
        named = None if procedure is None else (getattr(args, "procedure", None) or procedure.name)
        return sim_config(
            args.sim, bat=bat, session=session, ball_class=ball_class, speed_m_s=speed, balls_of=named
        )
    if args.config:
        return RigConfig.load(args.config)
    if not hasattr(args, "cannon"):
        raise ConfigError("give --sim [SCENE] or --config RIG.toml", source="command line")
    ports = {"cannon": args.cannon, "gates": args.gates, "clamp": args.clamp}
    missing = [f"--{k}" for k, v in ports.items() if not v]
    if missing:
        raise ConfigError(f"give --sim [SCENE], --config RIG.toml, or all of {', '.join(missing)}")
    return RigConfig.from_dict({"ports": ports}, source="command line")


def signoff_from(args: argparse.Namespace, flag: str) -> Any:
    """--who and --why for `flag` (a decision recorded with its taker and reason), as a Signoff."""
    from rig.certification import Signoff

    if not args.who or not args.why:
        raise ConfigError(f"{flag} needs --who NAME and --why TEXT (both recorded)", source="command line")
    return Signoff(args.who, args.why)


def sim_session(store: Any) -> str:
    """A simulated run's session: the store's count of runs so far, so that a test or certification
    run again (or resumed) in a store draws its own simulated noise, and a store replays alike."""
    return f"store-run-{len(store.runs())}"


def refuse_overwriting_store(target: Path, db: object) -> None:
    """ConfigError if writing `target` would overwrite the store file `db` (or its WAL, shared-memory
    or journal file); a database URL has no file to overwrite."""
    from rig.store import is_url

    if is_url(str(db)):
        return
    files = [Path(f"{db}{suffix}").resolve() for suffix in ("", "-wal", "-shm", "-journal")]
    if target.resolve() in files:
        raise ConfigError("--output would overwrite the record store (--db)", source=str(target))


def output_file(value: str | None, flag: str) -> Path | None:
    """The file a flag (--output, --plot, OUT) names, checked before any work: ConfigError if it
    names a folder, or if its folder does not exist (a missing folder is not made)."""
    if value is None:
        return None
    path = Path(value).expanduser()
    if path.is_dir() or value.endswith("/"):
        raise ConfigError(f"{value}: a folder; give a file name", source=flag)
    if not path.parent.is_dir():
        raise ConfigError(f"{value}: its folder {path.parent} does not exist (create it first)", source=flag)
    return path


def output_dir(value: str | None, flag: str) -> Path | None:
    """The folder a flag (--figures, --plot-dir) names: made if missing, but its own folder must
    exist; ConfigError if it is a file."""
    if value is None:
        return None
    path = Path(value).expanduser()
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{value}: not a folder", source=flag)
    if not path.parent.is_dir():
        raise ConfigError(f"{value}: its folder {path.parent} does not exist (create it first)", source=flag)
    return path


def default_db() -> Path | str:
    """Where records go when no --db is given: $RIG_DB, else rig-records.db in the working directory."""
    from rig.core.dbpath import default_db as where

    return where()


def shown_db(db: object) -> str:
    """A --db value as it may be printed: a database URL's password masked."""
    from rig.store import safe_url

    return safe_url(str(db))


def open_db(args: argparse.Namespace, *, readonly: bool = False) -> Any:
    """The store --db names (else the default); `readonly` for commands that only read it, so that a
    store on read-only media reads."""
    from rig.store import Store

    return Store.open(args.db or default_db(), create=getattr(args, "create_db", False), readonly=readonly)


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


def add_report_options(p: argparse.ArgumentParser) -> None:
    """--lab FILE and --operator NAME: what a new run records for its test report."""
    p.add_argument(
        "--lab",
        metavar="LAB.toml",
        help="the lab identity file its report names (name, address, accreditation id, logo); default "
        "$RIG_LAB, else the rig config's [identity] lab (recorded when the run is created)",
    )
    p.add_argument(
        "--operator",
        metavar="NAME",
        help="who performs the test (recorded; the report's 'test performed by')",
    )


def scene_names() -> str:
    """The built-in simulated scenes, from the scenes folder (simulators/scenes/*.toml), without
    loading the simulator (a command's help stays light)."""
    import rig.simulators

    folder = Path(rig.simulators.__file__).with_name("scenes")
    return ", ".join(sorted(p.stem for p in folder.glob("*.toml")))


def add_rig_options(p: argparse.ArgumentParser) -> None:
    """--sim [SCENE] or --config RIG.toml, one of them."""
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--sim",
        nargs="?",
        const="ideal",
        metavar="SCENE",
        help=f"simulated rig: a built-in scene ({scene_names()}; ideal if none named) or a scene TOML file",
    )
    where.add_argument("--config", metavar="RIG.toml", help="rig configuration file")
