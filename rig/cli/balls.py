"""`rig balls register|test|list|show|law`: ball lots in the store and the ball tests that measure them."""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path
from typing import Any

from rig.cli.common import (
    add_columns,
    add_rig_options,
    default_db,
    new_table,
    open_db,
    output_file,
    refuse_overwriting_store,
    resolve_run,
    shown_db,
    signoff_from,
    sim_session,
)
from rig.cli.common import console as out
from rig.core.dbpath import DB_HELP
from rig.core.errors import ConfigError, RecordRefused
from rig.protocols.names import BALL_BUILTIN


def cmd_register(args: argparse.Namespace) -> int:
    """rig balls register: record a ball lot (its [lot] table) in the store."""
    from rig.core.ball import BallLot

    lot = BallLot.load(args.lot_file)  # a bad file is refused in one line naming the field
    args.create_db = True
    with open_db(args) as store:
        try:
            entry = store.register_lot(lot)
        except RecordRefused as exc:
            raise ConfigError(str(exc), source=args.lot_file) from None
    print(f"registered ball lot {lot.id} ({lot.maker} {lot.model}, {lot.balls} balls) at seq {entry.seq}")
    return 0


def _accepted(args: argparse.Namespace) -> Any:
    """--accept-overdue with --who and --why, as a Signoff; None without it."""
    if not args.accept_overdue:
        if args.who or args.why:
            raise ConfigError("--who and --why go with --accept-overdue", source="command line")
        return None
    return signoff_from(args, "--accept-overdue")


def cmd_test(args: argparse.Namespace) -> int:
    """rig balls test: run a ball test (a built-in one or a TOML file) on a registered lot, recording
    everything."""
    from rig.ball_rules import refuse_other_balls
    from rig.balls import recorded_test, rehearse_test, run_ball_test
    from rig.core import events as ev
    from rig.protocols.ball_procedure import BallProcedure
    from rig.protocols.control import RunControl, ScriptedOperator
    from rig.report.live import LiveConsole
    from rig.run_signals import stop_on_signals

    accept_overdue = _accepted(args)  # the flags checked before anything is opened
    control = RunControl()
    args.create_db = not args.dry_run  # a dry run writes nothing, not even a new store
    with stop_on_signals(control), open_db(args) as store:
        if args.resume:
            run_id = resolve_run(store, args.resume)
            procedure, lot = recorded_test(store, run_id)
        else:
            if not args.procedure or not args.lot:
                raise ConfigError("give --procedure and --lot (or --resume RUN)", source="command line")
            procedure = BallProcedure.load(args.procedure)
            lots = store.ball_lots()
            if args.lot not in lots:
                known = ", ".join(lots) or "none yet"
                raise ConfigError(
                    f"no ball lot {args.lot!r} in {shown_db(store.location)} (registered: {known}); "
                    "rig balls register LOT.toml first",
                    source="--lot",
                )
            lot, run_id = lots[args.lot], None
            refuse_other_balls(lot, str(args.procedure), procedure.ball)
        config = _rig_config(args, procedure, sim_session(store))
        if args.dry_run:  # the rehearsal alone; a real test is rehearsed once, by run_ball_test
            past = ev.parse_log(store.entries(run_id)) if run_id is not None else None
            rehearsal = rehearse_test(procedure, lot, config, past)
            if rehearsal.problems:  # one line, every problem in it
                raise ConfigError("; ".join(rehearsal.problems), source="dry run")
            print(f"dry run: the test fits this rig and this lot ({rehearsal.summary()})", file=sys.stderr)
            return 0
        live = LiveConsole(quiet=args.json)
        outcome = run_ball_test(
            store,
            procedure,
            lot,
            config,
            run_id=run_id,
            operator=ScriptedOperator(who="script (--sim or scripted run)"),
            subscribers=[live],
            control=control,
            accept_overdue=accept_overdue,
        )
        live.close()
    if outcome.status != "finished":
        where = ("--config", args.config) if args.config else ("--sim", args.sim)
        db = f" --db {shlex.quote(shown_db(args.db))}" if args.db else ""
        sim_start = args.sim is not None and args.sim_start is not None
        start = f" --sim-start {args.sim_start!r}" if sim_start else ""  # the same hour of the lab's air
        rig = f"{where[0]} {shlex.quote(str(where[1]))}"
        resume = f"rig balls test --resume {outcome.run_id} {rig}{start}{db}"
        print(
            f"rig: run {outcome.run_id} interrupted: {outcome.reason}; resume with: {resume}", file=sys.stderr
        )
        return 3
    result = (outcome.verdict.lot_result if outcome.verdict else None) or {}
    if args.json:
        verdict = outcome.verdict.to_payload() if outcome.verdict else {}
        json.dump({"run_id": outcome.run_id, **verdict}, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(_result_line(lot.id, outcome.run_id, result))
    return 0


def _rig_config(args: argparse.Namespace, procedure: Any, session: str) -> Any:
    """The rig: a simulated one holds the procedure's target, as the lab clamps it (`session`: its
    own noise, rig.cli.common.sim_session)."""
    from rig.core.config import RigConfig

    if args.sim is not None:
        from rig.session import air_starting_at, sim_config

        at = None if args.sim_start is None else air_starting_at(args.sim_start)
        target = (procedure.target.kind, procedure.target.diameter_m)
        balls = procedure.ball.ball_class  # softballs of that class, as the lab loads them
        named = args.procedure or procedure.name
        return sim_config(
            args.sim, target=target, effects=at, session=session, ball_class=balls, balls_of=named
        )
    if args.sim_start is not None:
        raise ConfigError("--sim-start is for a simulated rig (--sim)", source="command line")
    if args.config:
        return RigConfig.load(args.config)
    raise ConfigError("give --sim [SCENE] or --config RIG.toml", source="command line")


def _result_line(lot_id: str, run_id: str, r: dict[str, Any]) -> str:
    name = r.get("quantity", "cor").upper()
    wear = r.get("wear_per_hit")
    parts = [
        f"lot {lot_id}: {name} {r['mean']:.4f} +- {r['U']:.4f} (U, k={r['coverage_k']:g})",
        f"{r['n_balls']} balls x {r['hits_per_ball']} hits",
    ]
    if r.get("sd_between_balls") is not None:
        parts.append(f"ball-to-ball SD {r['sd_between_balls']:.4f}")
    if wear is not None:
        parts.append(f"wear {wear:+.6f} +- {r['wear_per_hit_u']:.2g} per hit")  # u may be 1e-6
    return "; ".join(parts) + f" (run {run_id})"


def _lot_row(lot: Any, results: list[Any]) -> dict[str, Any]:
    last = results[-1] if results else None
    return {
        "lot": lot.model_dump(mode="json"),
        "results": [r.model_dump(mode="json", exclude={"points"}) for r in results],
        "latest": None if last is None else {"procedure": last.procedure, "mean": last.mean, "U": last.U},
    }


def cmd_list(args: argparse.Namespace) -> int:
    """rig balls list: the registered ball lots and their latest measured results."""
    with open_db(args) as store:
        lots = {lot_id: store.ball_lot(lot_id) for lot_id in store.ball_lots()}
    if args.json:
        json.dump([_lot_row(lot, results) for lot, results in lots.values()], sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    table = new_table(title=f"Ball lots in {shown_db(args.db or store.location)}")
    add_columns(
        table, "lot", "maker", "model", "balls", "nominal COR", "measured COR", "measured CCOR", "tests"
    )
    for lot, results in lots.values():
        latest = {r.procedure: r for r in results}
        cor, ccor = latest.get("ball-cor"), latest.get("ccor")
        table.add_row(
            lot.id,
            lot.maker,
            lot.model,
            str(lot.balls),
            "-" if lot.specification.nominal_cor is None else f"{lot.specification.nominal_cor:.3f}",
            "-" if cor is None else f"{cor.mean:.4f} +- {cor.U:.4f}",
            "-" if ccor is None else f"{ccor.mean:.4f} +- {ccor.U:.4f}",
            str(len(results)),
        )
    out().print(table)
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """rig balls show: one lot, its specification and conditioning, and every result measured."""
    with open_db(args) as store:
        lot, results = store.ball_lot(args.lot)
        laws = store.ball_laws(args.lot)
    if args.json:
        recorded = [{"sha256": w.sha256, "t_utc": w.t_utc, "entry": w.seq} for w in laws]
        json.dump({**_lot_row(lot, results), "ball_laws": recorded}, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    spec, cond = lot.specification, lot.conditioning
    print(f"lot {lot.id}: {lot.maker} {lot.model}, {lot.balls} balls")
    print(
        "  specification: "
        + (", ".join(f"{k} {v:g}" for k, v in spec.model_dump().items() if v is not None) or "none entered")
    )
    print(
        "  conditioning: "
        + (", ".join(f"{k} {v:g}" for k, v in cond.model_dump().items() if v is not None) or "not stated")
    )
    if not results:
        from rig.ball_rules import tests_for_lot

        fits = "|".join(tests_for_lot(lot)) or "TEST.toml (no built-in test fires this lot's balls)"
        print(f"  no results yet: rig balls test --procedure {fits} --lot {lot.id}")
    for r in results:
        print("  " + _result_line(lot.id, r.run_id, r.model_dump(mode="json")))
    for law in laws:
        print(f"  ball law recorded {law.t_utc} (sha256 {law.sha256[:12]}, entry {law.seq})")
    if laws:
        print(
            f"  the latest is the lot's: rig balls law {lot.id} --output BALL.json writes it"
            " (--entry SEQ an earlier one)"
        )
    return 0


def cmd_law(args: argparse.Namespace) -> int:
    """rig balls law: write the lot's recorded ball law (the file rig model fit-ball --db --lot wrote)."""
    from rig.report.export import atomic_write

    target = output_file(args.output, "--output")
    assert target is not None  # a required flag
    refuse_overwriting_store(target, args.db or default_db())
    with open_db(args) as store:
        store.ball_lot(args.lot)  # an unknown lot: one line naming the known ones
        recorded = store.ball_laws(args.lot)
    if not recorded:
        raise ConfigError(
            f"lot {args.lot} has no recorded ball law: rig model fit-ball --db STORE --lot {args.lot}"
            " --output BALL.json records one",
            source="rig balls law",
        )
    chosen = [w for w in recorded if args.entry is None or w.seq == args.entry]
    if not chosen:
        entries = ", ".join(str(w.seq) for w in recorded)
        raise ConfigError(f"lot {args.lot} has no ball law at entry {args.entry} (its laws: {entries})")
    last = chosen[-1]
    if not last.intact:
        raise ConfigError(f"lot {args.lot}'s ball law at entry {last.seq} does not match its recorded sha256")
    # as recorded, byte for byte (the recorded sha256), through a temporary file beside the target
    data = last.text.encode("utf-8")

    def write(tmp: Path) -> None:
        tmp.write_bytes(data)

    atomic_write(target, write)
    print(
        f"wrote {target}: lot {args.lot}'s ball law of {last.t_utc} (sha256 {last.sha256[:12]})",
        file=sys.stderr,
    )
    return 0


def add_parsers(sub: Any) -> None:
    """`rig balls ...`."""
    balls = sub.add_parser("balls", help=f"ball lots and ball tests ({', '.join(BALL_BUILTIN)})")
    bsub = balls.add_subparsers(dest="balls_command", required=True, metavar="BALLS_COMMAND")

    p = bsub.add_parser(
        "register", help="record a ball lot (LOT.toml, table [lot])", description=cmd_register.__doc__
    )
    p.add_argument("lot_file", metavar="LOT.toml", help="the lot's file (table [lot])")
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.set_defaults(handler=cmd_register)

    p = bsub.add_parser("test", help="run a ball test on a registered lot", description=cmd_test.__doc__)
    p.add_argument("--procedure", help=f"{', '.join(BALL_BUILTIN)} (built in), or a ball-test TOML file")
    p.add_argument("--lot", metavar="LOT", help="the registered lot's id")
    add_rig_options(p)
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--resume", metavar="RUN", help="resume an interrupted ball test")
    p.add_argument(
        "--sim-start",
        type=float,
        metavar="S",
        help="with --sim: the simulated lab's air starts S virtual s into its daily swing (ball-cor tests"
        " at several starts measure the lot's sensitivity to the air; the lab scene's swing is 3600 s)",
    )
    p.add_argument(
        "--accept-overdue",
        action="store_true",
        help="use instruments past their calibration due date for this test (--who, --why recorded)",
    )
    p.add_argument("--who", metavar="NAME", help="who accepts the overdue calibration (recorded)")
    p.add_argument("--why", metavar="TEXT", help="why (recorded)")
    p.add_argument("--dry-run", action="store_true", help="check the test against rig and lot only")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(handler=cmd_test)

    p = bsub.add_parser("list", help="the registered lots and their results", description=cmd_list.__doc__)
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_list)

    p = bsub.add_parser(
        "law", help="write the lot's recorded ball law to a file", description=cmd_law.__doc__
    )
    p.add_argument("lot", metavar="LOT", help="the lot's id")
    p.add_argument("--output", required=True, metavar="BALL.json", help="where to write the ball file")
    p.add_argument(
        "--entry", type=int, metavar="SEQ", help="the law recorded at this entry (see rig balls show)"
    )
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.set_defaults(handler=cmd_law)

    p = bsub.add_parser("show", help="one lot and every result", description=cmd_show.__doc__)
    p.add_argument("lot", metavar="LOT", help="the lot's id")
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_show)
