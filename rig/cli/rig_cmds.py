"""`rig shot` and `rig sim serve`: one recorded shot through the drivers, simulated devices out of process."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import (
    add_rig_options,
    emit,
    open_db,
    rig_config,
    scene_names,
)
from rig.core.dbpath import DB_HELP
from rig.core.errors import ConfigError

MAX_BASE_PORT = 65533  # the cannon's port; gates and clamp take the next two


def cmd_shot(args: argparse.Namespace) -> int:
    """rig shot: fire one shot through the drivers, recorded as a one-shot run, and print the raw
    and derived figures.

    The run (kind `shot` in `rig runs`; no verdict) records the intent before FIRE, the raw record
    and the speeds, as a certification's shots are; `rig verify` checks it. A cannon an earlier shot
    left in FAULT (a misfire) is reset to SAFE first, and the user told.
    """
    from rig.one_shot import OneShot, ShotNotMeasured, fire_one_shot, rehearse_shot

    config = rig_config(args)
    at = config.impact_from_pivot_m if args.impact_from_pivot is None else args.impact_from_pivot
    rehearsed = rehearse_shot(config, OneShot(speed_m_s=args.speed, impact_from_pivot_m=at))
    args.create_db = True  # a shot the rig cannot give was refused above: no store made for it
    with open_db(args) as store:
        done = fire_one_shot(store, rehearsed, said=lambda text: print(f"rig: {text}", file=sys.stderr))
    payload = {"run_id": done.run_id, **done.record}
    if not done.measured:
        reason = "; ".join(str(r) for r in done.evaluation.reasons) or "the speeds were not measured"
        if args.json:
            json.dump({"error": reason, **payload}, sys.stderr, allow_nan=False)
            sys.stderr.write("\n")
        raise ShotNotMeasured(f"{reason} (recorded as run {done.run_id})")
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        shown = {k: v for k, v in payload.items() if k not in ("crossings", "extra_crossings")}
        shown["crossings"] = " ".join(f"G{c['gate']}@{c['tick']}" for c in payload["crossings"])
        args.json = False
        emit(args, shown, f"Shot {done.record['shot_number']}")
    if done.signing.startswith("warning"):
        print(done.signing, file=sys.stderr)
    return 0


def cmd_sim_serve(args: argparse.Namespace) -> int:
    """rig sim serve: expose the simulated devices on ptys or TCP ports until interrupted.

    With --instruments each device is served by the twin of a real instrument class at its own
    wire level (a SCPI counter, a Modbus PLC, a VXM stage with its swing sensor; a scene whose barrel
    rolling softens, such as composite, also its barrel-compression tester), and --write-config
    writes the rig config that names their drivers.

    The physics is loaded and one dummy shot fired before the ports are printed, so that the first
    FIRE is answered as fast as any other. With --bat, the simulated bat takes the bat file's
    properties as its true ones (those the scene's [bat] table sets win), as `--sim` does for a run.
    """
    from pydantic import ValidationError

    from rig.simulators.scene import Scene
    from rig.simulators.serve import serve

    scene = Scene.load(args.scene)
    if args.bat is not None:
        from rig.core.bat import BatSpec
        from rig.session import scene_with_bat

        bat = BatSpec.load(args.bat)  # a bad file is refused naming itself
        try:
            scene = scene_with_bat(scene, bat)
        except ValidationError as exc:
            reason = exc.errors()[0]["msg"].removeprefix("Value error, ")
            raise ConfigError(f"this bat does not fit scene {args.scene!r}: {reason}", args.bat) from None
        except ConfigError as exc:  # the scene's own refusal: say which file it was about
            reason = exc.reason.removeprefix("Value error, ")
            raise ConfigError(f"this bat does not fit scene {args.scene!r}: {reason}", args.bat) from None
    if args.instruments:
        from rig.cli.common import output_file
        from rig.simulators.instruments.serve import serve_instruments

        if args.kind is not None:
            raise ConfigError(
                "--instruments serves TCP ports of 127.0.0.1: drop --kind", source="command line"
            )
        target = output_file(args.write_config, "--write-config")
        serve_instruments(
            scene,
            base_port=args.base_port,
            write_config=target,
            chosen=dict(args.twin or []),
            serial=args.serial,
        )
        return 0
    if args.write_config is not None or args.twin or args.serial:
        what = "--write-config" if args.write_config is not None else "--twin" if args.twin else "--serial"
        raise ConfigError(f"{what} goes with --instruments", source="command line")
    serve(scene, kind=args.kind or "pty", base_port=args.base_port)
    return 0


def _base_port(text: str) -> int:
    """A TCP port for the cannon, with room for the gates and the clamp on the next two; 0: any."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= port <= MAX_BASE_PORT:
        raise argparse.ArgumentTypeError(f"{port} is not a port from 1 to {MAX_BASE_PORT} (or 0: any free)")
    return port


def _twin_choice(text: str) -> tuple[str, str]:
    """KIND=DRIVER of --twin."""
    kind, sep, driver = text.partition("=")
    if not sep or not kind.strip() or not driver.strip():
        raise argparse.ArgumentTypeError(f"{text!r} is not KIND=DRIVER (e.g. gates=scpi-counter)")
    return kind.strip(), driver.strip()


def add_parsers(sub: Any) -> None:
    """`rig shot` and `rig sim serve`."""
    p = sub.add_parser("shot", help="fire one shot through the drivers", description=cmd_shot.__doc__)
    add_rig_options(p)
    p.add_argument("--cannon", metavar="URL", help="cannon port URL (device path, socket://, sim://)")
    p.add_argument("--gates", metavar="URL", help="light-gate port URL")
    p.add_argument("--clamp", metavar="URL", help="pivot-clamp port URL")
    p.add_argument("--speed", type=float, required=True, help="target inbound speed, m/s")
    p.add_argument("--impact-from-pivot", type=float, help="impact point from the pivot, m")
    p.add_argument("--db", metavar="FILE", help=DB_HELP + " (the shot is recorded as a one-shot run)")
    p.add_argument("--json", action="store_true", help="print the shot record as JSON")
    p.set_defaults(handler=cmd_shot)

    sim = sub.add_parser("sim", help="simulated hardware")
    ssub = sim.add_subparsers(dest="sim_command", required=True, metavar="SIM_COMMAND")
    p = ssub.add_parser(
        "serve", help="expose simulated devices out of process", description=cmd_sim_serve.__doc__
    )
    p.add_argument(
        "--scene", default="ideal", help=f"a built-in scene ({scene_names()}) or a scene TOML file"
    )
    p.add_argument("--kind", choices=("pty", "tcp"), help="pty (default) or tcp on 127.0.0.1")
    p.add_argument(
        "--instruments",
        action="store_true",
        help="serve the devices through real-instrument twins (SCPI counter, Modbus PLC, VXM stage) on TCP; "
        "a scene whose barrel softens (composite) also serves the barrel-compression tester",
    )
    p.add_argument(
        "--write-config",
        metavar="RIG.toml",
        help="with --instruments: write the rig config that names the three drivers (rig certify --config)",
    )
    p.add_argument(
        "--serial",
        action="store_true",
        help="with --instruments: the PLC (Modbus RTU), the stage and the sensor on ptys, as serial ports",
    )
    p.add_argument(
        "--twin",
        type=_twin_choice,
        action="append",
        metavar="KIND=DRIVER",
        help="with --instruments: serve device KIND by DRIVER's twin (default: the first built-in with one)",
    )
    p.add_argument(
        "--base-port",
        type=_base_port,
        default=0,
        help="first of the consecutive TCP ports (default: any free ports)",
    )
    p.add_argument(
        "--bat", metavar="BAT.toml", help="simulate this bat (its length, mass, MOI, balance, hoop)"
    )
    p.set_defaults(handler=cmd_sim_serve)
