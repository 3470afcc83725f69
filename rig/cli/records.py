"""`rig certify`, `runs`, `report`, `verify`, `tui`: certification runs and their records."""

from __future__ import annotations

import argparse
import contextlib
import json
import shlex
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rig.cli.common import (
    ConfigError,
    add_columns,
    add_report_options,
    add_rig_options,
    default_db,
    new_table,
    open_db,
    output_dir,
    output_file,
    resolve_run,
    rig_config,
    shown_db,
    signoff_from,
    sim_session,
)
from rig.cli.common import console as out
from rig.core.dbpath import DB_HELP
from rig.measure.registry import BUILTIN_PROCEDURES


def _resume_command(store: Any, run_id: str, args: argparse.Namespace) -> str:
    """`rig certify --resume RUN ...` as the operator types it: the rig and store of this command;
    for a run that never started, also what it starts with (a procedure file, balls, calibration)."""
    from rig.break_in import ABI
    from rig.core import events as ev
    from rig.protocols.procedure import BUILTIN

    where = ("--config", args.config) if args.config else ("--sim", args.sim) if args.sim else None
    rig = f"{where[0]} {shlex.quote(where[1])}" if where else "--config RIG.toml"
    db = f" --db {shlex.quote(shown_db(args.db))}" if args.db else ""
    inputs = ""
    if not store.entries(run_id, kinds=[ev.RUN_STARTED]):
        given = [("--ball-lot", args.ball_lot), ("--ball", args.ball), ("--calibration", args.calibration)]
        if args.procedure and args.procedure not in (*BUILTIN, ABI):
            given.insert(0, ("--procedure", args.procedure))
        inputs = "".join(f" {flag} {shlex.quote(str(value))}" for flag, value in given if value)
    if args.sim and args.bat:  # the simulated bat's truth ([simulated]) is in its file, not the record
        inputs += f" --bat {shlex.quote(str(args.bat))}"
    return f"rig certify --resume {run_id} {rig}{db}{inputs}"


def _interrupted(outcome: Any, args: argparse.Namespace, resume: str) -> int:
    """Tell the operator how to go on after an interruption; exit status 3."""
    db = f" --db {shlex.quote(shown_db(args.db))}" if args.db else ""
    print(f"rig: run {outcome.run_id} interrupted: {outcome.reason}; resume with: {resume}", file=sys.stderr)
    if outcome.budget_exceeded:
        print(
            "rig: once the rig is checked, resume with the check recorded (the re-shoot budget starts "
            f"again): {resume} --rig-checked --who NAME --why TEXT; or end the run with no verdict: "
            f"rig certify --end {outcome.run_id}{db} --who NAME --why TEXT",
            file=sys.stderr,
        )
    return 3


def _end(args: argparse.Namespace) -> int:
    from rig.certification import end_run

    signoff = signoff_from(args, "--end")
    with open_db(args) as store:
        outcome = end_run(store, resolve_run(store, args.end), signoff)
    print(f"run {outcome.run_id} {outcome.reason}")  # a success: stdout, no error prefix
    if outcome.signing.startswith("warning"):
        print(outcome.signing, file=sys.stderr)
    return 0


def cmd_certify(args: argparse.Namespace) -> int:
    """rig certify: run a certification procedure on a bat, live, recording everything."""
    from rig.break_in import load_procedure, recorded_plan
    from rig.certification import RunNotRecorded, prepare, run_prepared
    from rig.cli.abi_run import run_operator
    from rig.core.bat import BatSpec
    from rig.core.errors import StoreError
    from rig.protocols.abi import abi
    from rig.protocols.control import RunControl
    from rig.report.live import LiveConsole
    from rig.report.record import run_record
    from rig.request import CertifyRequest, calibrated
    from rig.run_signals import stop_on_signals

    if args.end:
        if (
            args.resume
            or args.procedure
            or args.bat
            or args.rig_checked
            or args.ball_lot
            or args.ball
            or args.accept_overdue
        ):
            raise ConfigError("--end takes only the run, --who and --why", source="command line")
        return _end(args)
    if args.rig_checked and not args.resume:
        raise ConfigError("--rig-checked goes with --resume RUN", source="command line")
    rig_checked = signoff_from(args, "--rig-checked") if args.rig_checked else None
    if args.accept_overdue and args.rig_checked:
        raise ConfigError(
            "--accept-overdue and --rig-checked each need their own --who/--why: give one",
            source="command line",
        )
    accept_overdue = signoff_from(args, "--accept-overdue") if args.accept_overdue else None
    control = RunControl()
    args.create_db = True
    with contextlib.ExitStack() as stack:
        stack.enter_context(stop_on_signals(control))
        store = stack.enter_context(_certify_store(args))
        ball: dict[str, Any] | None = None  # a resumed run keeps the ball terms it recorded
        started = True
        if args.resume:
            from rig.resume import recorded_inputs

            run_id = resolve_run(store, args.resume)
            given = load_procedure(args.procedure)[0] if args.procedure else None
            recorded = recorded_inputs(store, run_id, given)  # never started: what its RunCreated names
            procedure, bat, started = recorded.procedure, recorded.bat, recorded.started
            plan = recorded_plan(recorded.plan, run_id)  # the plan it was started with (the ABI's)
            if args.bat:  # the same bat's file: a simulated rig takes its [simulated] truth again
                bat = _same_bat(BatSpec.load(args.bat), bat, args.bat)
            if started and (args.ball_lot or args.ball):
                raise ConfigError(
                    "a resumed run keeps the balls it recorded: drop --ball-lot and --ball", source="--resume"
                )
            if not started:  # it starts now: with the balls given, as a new run would
                ball = _ball_terms(store, args, procedure)
        else:
            if not args.procedure or not args.bat:
                raise ConfigError("give --procedure and --bat (or --resume RUN)", source="command line")
            (procedure, plan), bat = load_procedure(args.procedure), BatSpec.load(args.bat)
            run_id = None
            ball = _ball_terms(store, args, procedure)
        if args.resume and (args.lab or args.operator):
            raise ConfigError(
                "--lab and --operator are recorded when a run is created; a resumed run keeps its own",
                source="command line",
            )
        if args.calibration and args.resume and started:
            raise ConfigError(
                "--calibration starts a run; a resumed run keeps the calibration it recorded",
                source="command line",
            )
        live = LiveConsole(quiet=args.json)
        # who answers (an ABI's rollings: a person at a terminal, else the script rolling a simulated barrel)
        operator, rig_for = stack.enter_context(run_operator(args, store, run_id, plan is abi, control))
        request = CertifyRequest(
            procedure,
            bat,
            # built once the bat has its measured hoop: a simulated bat takes it as its own
            lambda measured: rig_for(
                calibrated(
                    rig_config(args, bat=measured, session=sim_session(store), procedure=procedure),
                    args.calibration,
                    "command line",
                )
            ),
            run_id=run_id,
            plan=plan,
            operator=operator,
            subscribers=(live,),
            control=control,
            rig_checked=rig_checked,
            ball=ball,
            sign_simulated=args.sign_simulated,
            accept_overdue=accept_overdue,
            lab=args.lab,
            tested_by=args.operator,
        )
        prepared = prepare(store, request)  # the one rehearsal (a resumed run: what is left of it)
        if args.dry_run:
            summary = prepared.rehearsal.summary()
            print(f"dry run: the procedure fits this rig and this bat ({summary})", file=sys.stderr)
            return 0
        if control.aborted:  # a signal before anything was recorded: nothing to resume
            print("rig: stopped by a signal before the run started; nothing recorded", file=sys.stderr)
            return 3
        try:
            outcome = run_prepared(store, prepared)
        except RunNotRecorded as exc:  # the store failed the run: one line, and how to go on if it can
            hint = ""
            if exc.resumable:
                resume = _resume_command(store, exc.run_id, args)
                hint = f"; once the store takes writes again, resume with: {resume}"
            raise StoreError(f"{exc}{hint}") from None
        finally:
            live.close()
        if args.resume and args.sim is not None and not args.bat:
            print(
                "rig: note: this simulated run was resumed without --bat: the recorded bat's properties "
                "were its truth (give the bat's file with --bat if it has a [simulated] table)",
                file=sys.stderr,
            )
        resume = _resume_command(store, outcome.run_id, args) if outcome.status != "finished" else ""
        if args.json:
            json.dump(run_record(store, outcome.run_id), sys.stdout, indent=2, allow_nan=False)
            sys.stdout.write("\n")
        else:
            live.summary(outcome)
    if outcome.status != "finished":
        return _interrupted(outcome, args, resume)
    return 0 if outcome.verdict and outcome.verdict.passed else 1


def _same_bat(given: Any, recorded: Any, path: str) -> Any:
    """The bat file (a BatSpec) given with --resume: the recorded bat (else ConfigError), with its truth."""
    if given != recorded:  # equality leaves the [simulated] truth aside: it is not the bat's record
        raise ConfigError(
            f"{path} is not the bat the run recorded ({recorded.id}): a resumed run keeps its bat",
            source="--bat",
        )
    return given


def _ball_terms(store: Any, args: argparse.Namespace, procedure: Any) -> dict[str, Any] | None:
    """The ball terms `--ball-lot` and `--ball` give (recorded in RunStarted), None for neither."""
    from rig.ball_rules import law_terms, lot_terms
    from rig.cli.fit_ball import load_ball

    law, sha = load_ball(args.ball) if args.ball else (None, None)
    name = Path(args.ball).name if args.ball else None  # the file's name, not this machine's path
    if args.ball_lot:  # without --ball, the lot's recorded law (rig model fit-ball --db --lot) if any
        return lot_terms(store, args.ball_lot, procedure, law, sha, name).model_dump(mode="json")
    return None if law is None else law_terms(law, sha, name).model_dump(mode="json")


@contextlib.contextmanager
def _certify_store(args: argparse.Namespace) -> Iterator[Any]:
    """The store a certification records into; a dry run of a new run creates none (a store that is
    not there yet is stood in for by a throwaway one: it has nothing to look up)."""
    from rig.store import Store, is_url

    where = args.db or default_db()
    if args.dry_run and not args.resume and not is_url(where) and not Path(where).exists():
        with (
            tempfile.TemporaryDirectory(prefix="rig-dry-run-") as tmp,
            Store.open(Path(tmp, "dry.db")) as store,
        ):
            yield store
        return
    with open_db(args) as store:
        yield store


def cmd_runs(args: argparse.Namespace) -> int:
    """rig runs: the recorded runs, newest last."""
    from rig.store import shown_status

    with open_db(args, readonly=True) as store:
        runs = store.runs()
        shown = {r.run_id: shown_status(store, r) for r in runs}  # one word, as every output shows it
        rigs = _rigs(store)
    if args.rig is not None:
        runs = [r for r in runs if (rigs.get(r.run_id) or {}).get("name") == args.rig]
    if args.json:
        rows = [
            {
                **r.__dict__,
                "status": shown[r.run_id],
                "interrupted": shown[r.run_id] == "interrupted",
                "rig": rigs.get(r.run_id),
            }
            for r in runs
        ]
        json.dump(rows, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    table = new_table(title=f"Runs in {shown_db(args.db or default_db())}")
    add_columns(table, "run", "procedure", "bat", "rig", "started (UTC)", "status", "verdict")
    for r in runs:
        status = shown[r.run_id]
        rig = (rigs.get(r.run_id) or {}).get("name") or "-"
        table.add_row(r.run_id[:12], r.procedure, r.bat_id, rig, r.started_utc, status, r.verdict or "")
    out().print(table)
    return 0


def _rigs(store: Any) -> dict[str, dict[str, Any] | None]:
    """Each run's recorded rig identity {name, serial, software} (None: recorded before rigs had one)."""
    rigs: dict[str, dict[str, Any] | None] = {}
    for entry in store.entries(kinds=["RunCreated"]):
        meta = entry.payload.get("meta")
        rig = meta.get("rig") if isinstance(meta, dict) else None
        rigs[entry.run_id] = rig if isinstance(rig, dict) else None
    return rigs


def cmd_report(args: argparse.Namespace) -> int:
    """rig report: a run's record as JSON, or its certificate as Markdown or HTML."""
    from rig.report.record import run_record
    from rig.store import Anchor

    if args.json:
        if args.format not in (None, "json"):
            raise ConfigError(
                f"--json is --format json; it cannot go with --format {args.format}", source="--json"
            )
        args.format = "json"
    args.format = args.format or "md"
    if args.format == "html" and not args.output and sys.stdout.isatty():
        raise ConfigError(
            "an HTML certificate is not for reading on a terminal: write it to a file with "
            "--output FILE.html and open that in a browser",
            source="--format html",
        )
    output_file(args.output, "--output")
    output_dir(args.figures, "--figures")
    anchor = Anchor.parse(args.anchor) if args.anchor else None
    if bool(args.issue) != bool(args.by):
        raise ConfigError("--issue needs --by NAME (who authorises the report), and --by goes with --issue")
    from rig.core.events import ONE_SHOT_KIND as ONE_SHOT
    from rig.report.ball_lot import is_ball_test, lot_record

    with open_db(args, readonly=not args.issue) as store:
        run_id = resolve_run(store, args.run)
        if args.issue:
            from rig.report.issue import issue

            done = issue(store, run_id, args.by)
            print(
                f"issued report {done['report_id']} of run {run_id} on {done['issued']} by {done['by']}",
                file=sys.stderr,
            )
        if args.format != "json" and store.run(run_id).procedure == ONE_SHOT:
            raise ConfigError(
                f"run {run_id} is a one-shot run (rig shot), not a certification: it has no certificate;"
                " --format json gives its record"
            )
        ball = is_ball_test(store, run_id)
        record = lot_record(store, run_id, anchor) if ball else run_record(store, run_id, anchor)
    if args.format == "json":
        text = json.dumps(record, indent=2, allow_nan=False) + "\n"
    elif ball:  # a ball test's report: the lot-result tables, no figures
        from rig.report.ball_lot import render as render_lot

        text = render_lot(record, args.format)
    else:
        from rig.progress import steps
        from rig.report.certificate import render

        drawn = args.format == "html" or args.figures is not None
        with steps(1 if drawn else 0, "certificate: drawing its figures" if drawn else "certificate") as bar:
            text = render(record, args.format, figures_dir=args.figures, output=args.output)
            bar.advance()
    if args.output:
        Path(args.output).write_text(text, encoding="utf-8")
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    if record["coverage"]["left_out"]:
        print(f"rig report: {record['coverage']['text']}", file=sys.stderr)
    return 0


def cmd_tui(args: argparse.Namespace) -> int:
    """rig tui: the operator's console (set-up, live run, history) in the terminal."""
    from rig.tui import ConsoleSettings, RigConsole

    if args.sim is None and not args.config:
        raise ConfigError("give --sim [SCENE] or --config RIG.toml", source="command line")
    if args.procedure:  # the break-in is refused before the console starts: one line (rig.tui.jobs)
        from rig.tui.jobs import refuse_break_in

        refuse_break_in(args.procedure)
    settings = ConsoleSettings.from_args(
        args.sim, args.config, args.db or default_db(), bat=args.bat or "", procedure=args.procedure or ""
    )
    console = RigConsole(settings)
    console.run()
    db = f" --db {shlex.quote(shown_db(args.db))}" if args.db else ""
    for left in console.left_open:  # as rig certify says it of an interrupted run: exit 3
        rig = f"--{left.rig.kind} {shlex.quote(left.rig.ref)}" if left.rig else "--config RIG.toml"
        print(
            f"rig: run {left.run_id} interrupted: {left.reason}; resume with: rig certify --resume "
            f"{left.run_id} {rig}{db}, or in rig tui {rig}{db}: h, the run, r",
            file=sys.stderr,
        )
    return 3 if console.left_open else 0


def cmd_verify(args: argparse.Namespace) -> int:
    """rig verify: recompute the hash chain, check each run and the anchor; exit 1 if anything is wrong."""
    import dataclasses

    from rig.keys import keys_in, parse_trusted, untrusted
    from rig.store import Anchor

    anchors = [Anchor.parse(args.anchor)] if args.anchor else []
    pins = parse_trusted(args.trusted_key)
    with open_db(args, readonly=True) as store:
        if args.run:
            if anchors:
                raise ConfigError("--anchor checks the whole store; leave out --run", source="command line")
            report = store.verify_run(resolve_run(store, args.run))
        else:
            report = store.verify(anchors)
        distrusted = untrusted(keys_in(store), pins) if pins else []
        if report.ok or report.first_broken_seq is None:  # the chain holds: do the results follow from it?
            from rig.balls import ball_terms_problems, recomputed_problems

            distrusted += recomputed_problems(store) + ball_terms_problems(store)
    if distrusted:
        report = dataclasses.replace(report, ok=False, problems=report.problems + tuple(distrusted))
    signatures = (
        f"{report.runs_signed} runs signed, {report.runs_unsigned} unsigned, {report.runs_bad_signature} bad"
    ) + _unlisted(report.unlisted_signatures)
    if args.json:
        json.dump(_verify_json(report), sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0 if report.ok else 1
    if report.ok:
        print(
            f"ok: {report.entries_checked} entries, chain intact; head {report.head.seq}:{report.head.hash}"
        )
        print(signatures)
        return 0
    if report.first_broken_seq is not None:
        print(f"ALTERED: first broken entry {report.first_broken_seq}: {report.reason}")
    else:
        print(f"ALTERED: the chain links, but {len(report.problems)} problem(s) were found:")
    for problem in report.problems:
        print(f"  {problem}")
    print(signatures)
    return 1


def _unlisted(rigs: tuple[str, ...]) -> str:
    """A word on unsigned runs whose signature names a key the store does not list (uncheckable)."""
    if not rigs:
        return ""
    n, names = len(rigs), ", ".join(sorted(set(rigs)))
    runs = "1 unsigned run carries" if n == 1 else f"{n} unsigned runs carry"
    return (
        f"\n{runs} a signature by a key this store does not list (rig {names}): "
        "rig keys register --rig NAME lists it, and verify then checks it"
    )


def _verify_json(report: Any) -> dict[str, Any]:
    """The verification as data: verdict, entries checked, head, where the chain broke, problems."""
    return {
        "ok": report.ok,
        "entries_checked": report.entries_checked,
        "head": {"seq": report.head.seq, "hash": report.head.hash},
        "first_broken_seq": report.first_broken_seq,
        "reason": report.reason,
        "problems": list(report.problems),
        "runs_signed": report.runs_signed,
        "runs_unsigned": report.runs_unsigned,
        "runs_bad_signature": report.runs_bad_signature,
        "unlisted_signatures": list(report.unlisted_signatures),
    }


def add_parsers(sub: Any) -> None:
    """`rig certify|runs|report|verify|tui`, in this order: the everyday tasks lead `rig --help`."""
    p = sub.add_parser(
        "certify",
        help=f"certify a bat ({', '.join(n for _, n in BUILTIN_PROCEDURES)}, abi)",
        description=cmd_certify.__doc__,
    )
    p.add_argument(
        "--procedure",
        help=f"{', '.join(n for _, n in BUILTIN_PROCEDURES)}, abi (the NCAA accelerated break-in of a "
        "composite bat: BBCOR before and after rolling stages), or a procedure TOML file",
    )
    p.add_argument(
        "--rolled-by",
        metavar="NAME",
        help="with --procedure abi: who rolls the barrel (recorded with each rolling; at a terminal the "
        "default the rolling prompt offers)",
    )
    p.add_argument(
        "--bat",
        metavar="BAT.toml",
        help="bat file (table [bat]); with --resume, the recorded bat's own file, whose [simulated] "
        "truth a simulated rig takes again (the record keeps only the bat)",
    )
    add_rig_options(p)
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--resume", metavar="RUN", help="resume an interrupted run")
    p.add_argument(
        "--calibration",
        metavar="CAL.json",
        help="model calibration for the cross-check (rig model calibrate); wins over the config [model]",
    )
    p.add_argument(
        "--ball-lot",
        metavar="LOT",
        help="the balls come from this lot in the store (rig balls register; qualified by a ball-cor test):"
        " its measured wear, spread and air sensitivities correct and budget the verdict, its rules hold",
    )
    p.add_argument(
        "--ball",
        metavar="BALL.json",
        help="the ball law fitted by rig model fit-ball (recorded; the ball terms' model ratio uses it)",
    )
    p.add_argument(
        "--rig-checked",
        action="store_true",
        help="with --resume: record that the rig was checked (--who, --why); the re-shoot budget restarts",
    )
    p.add_argument(
        "--accept-overdue",
        action="store_true",
        help="use instruments past their calibration due date for this run (--who, --why recorded)",
    )
    p.add_argument(
        "--end", metavar="RUN", help="end an unfinished run with no verdict (--who, --why recorded)"
    )
    p.add_argument(
        "--sign-simulated",
        action="store_true",
        help="sign a simulated run with its rig's key even where that key is not registered, or is a real"
        " rig's (by default a simulated run is signed only where its sim-SCENE key is registered)",
    )
    p.add_argument(
        "--who",
        metavar="NAME",
        help="who checked the rig, accepts an overdue calibration or ends the run (recorded)",
    )
    p.add_argument("--why", metavar="TEXT", help="why (recorded)")
    p.add_argument("--dry-run", action="store_true", help="check the procedure against rig and bat only")
    p.add_argument("--json", action="store_true", help="print the run record as JSON")
    add_report_options(p)
    p.set_defaults(handler=cmd_certify)

    p = sub.add_parser("runs", help="list recorded runs", description=cmd_runs.__doc__)
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--rig", metavar="NAME", help="only the runs of this rig (its identity name)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_runs)

    p = sub.add_parser("report", help="a run's record or certificate", description=cmd_report.__doc__)
    p.add_argument("run", metavar="RUN", help="run id (a unique prefix will do), or 'last'")
    p.add_argument("--format", choices=("json", "md", "html"), help="output format (default md)")
    p.add_argument("--json", action="store_true", help="the run record as JSON (the same as --format json)")
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument(
        "--output",
        "-o",
        metavar="FILE",
        help="write to a file instead of stdout (HTML: needed on a terminal)",
    )
    p.add_argument(
        "--figures",
        metavar="DIR",
        help="draw the certificate's plots as PNG files into DIR (Markdown links them; without it Markdown"
        " has no figures and nothing is written; HTML always embeds them as SVG)",
    )
    p.add_argument(
        "--anchor", metavar="SEQ:HASH", help="show the run only as far as this anchor (from a certificate)"
    )
    p.add_argument(
        "--issue",
        action="store_true",
        help="issue the report (recorded: report id, today's date, --by): it is no longer a draft",
    )
    p.add_argument("--by", metavar="NAME", help="with --issue: who authorises the report (recorded)")
    p.set_defaults(handler=cmd_report)

    p = sub.add_parser("verify", help="check the records' hash chain", description=cmd_verify.__doc__)
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--anchor", metavar="SEQ:HASH", help="a head hash printed on a certificate")
    p.add_argument("--run", metavar="RUN", help="only this run: its chain and its anchors in the lab chain")
    p.add_argument(
        "--trusted-key",
        action="append",
        default=[],
        metavar="RIG:FINGERPRINT",
        help="a rig's key fingerprint kept outside the store: any other key registered for it is reported",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON (exit status as without)")
    p.set_defaults(handler=cmd_verify)

    p = sub.add_parser("tui", help="the operator's console (terminal UI)", description=cmd_tui.__doc__)
    add_rig_options(p)
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--bat", metavar="BAT.toml", help="preselect this bat file")
    p.add_argument(
        "--procedure",
        help=f"preselect {', '.join(n for _, n in BUILTIN_PROCEDURES)} or a procedure TOML file",
    )
    p.set_defaults(handler=cmd_tui)
