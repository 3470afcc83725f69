"""`rig check [--bat REF.toml]`, `rig check chart`, `rig check ack`, `rig check restart`: the check
standard on control charts."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import (
    add_columns,
    add_rig_options,
    new_table,
    open_db,
    output_file,
    positive_int,
    rig_config,
    signoff_from,
    sim_session,
)
from rig.cli.common import console as out
from rig.core.dbpath import DB_HELP
from rig.core.errors import ConfigError

WHO = "rig check (scripted)"


def cmd_check(args: argparse.Namespace) -> int:
    """rig check: one check session on the lab's reference bat (protocols/check.toml: a fixed
    location, N hits), recorded as a run of kind `check`; then the rig's chart state."""
    from rig.certification import end_run
    from rig.check import check_procedure, prepare_check, run_check
    from rig.core.bat import BatSpec
    from rig.protocols.control import RunControl, ScriptedOperator
    from rig.report.live import LiveConsole
    from rig.request import CertifyRequest, Signoff
    from rig.run_signals import stop_on_signals

    if not args.bat:
        raise ConfigError("give --bat REF.toml (the reference bat), or a subcommand: chart, ack")
    procedure = check_procedure(args.procedure, args.hits)
    bat = BatSpec.load(args.bat)
    control = RunControl()
    args.create_db = True
    with stop_on_signals(control), open_db(args) as store:
        live = LiveConsole(quiet=args.json)
        request = CertifyRequest(
            procedure,
            bat,
            lambda measured: rig_config(args, bat=measured, session=sim_session(store)),
            operator=ScriptedOperator(who=WHO),
            subscribers=(live,),
            control=control,
        )
        prepared = prepare_check(store, request)
        try:
            outcome = run_check(store, prepared)
        finally:
            live.close()
        if outcome.status != "finished":  # a check is not resumed: ended, recorded, and run again
            end_run(store, outcome.run_id, Signoff(WHO, f"check interrupted: {outcome.reason}"[:500]))
            raise ConfigError(
                f"check run {outcome.run_id} stopped ({outcome.reason}); "
                "it is ended (recorded): run the check again",
                source="rig check",
            )
        quality = _quality(store, prepared.config.identity_name(), args)
    verdict = outcome.verdict
    hits = list(verdict.hits or []) if verdict else []
    payload = {
        "run_id": outcome.run_id,
        "rig": quality.rig,
        "bat": bat.id,
        "metric": procedure.standard,
        "hits": hits,
        "mean": verdict.mean if verdict else None,
        "state": quality.state(),
        "signals": [s.describe() for _, s in quality.unacknowledged],
    }
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(
            f"check run {outcome.run_id}: {len(hits)} hits, mean {procedure.standard} {payload['mean']:.5f}"
        )
        print(f"rig {quality.rig}: {quality.state()}")
        for text in payload["signals"]:
            print(f"  signal: {text}")
    return 0


def _quality(store: Any, rig: str, args: argparse.Namespace) -> Any:
    from rig.quality.records import rig_quality

    return rig_quality(store, rig, getattr(args, "phase_i", None) or 20)


def cmd_chart(args: argparse.Namespace) -> int:
    """rig check chart: per rig and reference bat, the individuals, EWMA and s charts of the check
    runs, phase I stated, and every signal (acknowledged or not)."""
    from rig.quality.records import check_series

    plot = output_file(args.plot, "--plot")
    if args.crosscheck:
        return _crosscheck_chart(args, plot)
    if args.model is not None:
        raise ConfigError("--model goes with --crosscheck", source="command line")
    with open_db(args, readonly=True) as store:
        series, _ = check_series(store)
        rigs = sorted({s.rig for s in series if args.rig in (None, s.rig)})
        if args.rig and not rigs:
            raise ConfigError(f"no check runs of rig {args.rig} in this store", source="--rig")
        states = [_quality(store, rig, args) for rig in rigs]
    shown = [(q, bat, c) for q in states for bat, c in sorted(q.charts.items()) if args.bat in (None, bat)]
    if args.bat and not shown:
        raise ConfigError(f"no check runs of reference bat {args.bat}", source="--bat")
    if plot is not None:
        if len(shown) != 1:
            raise ConfigError(
                f"--plot draws one rig's charts of one reference bat; {len(shown)} match: "
                "give --rig and --bat",
                source="--plot",
            )
        from rig.report.quality_plots import plot_charts

        q, bat, c = shown[0]
        plot_charts(c, f"check standard {bat} on rig {q.rig}", plot, q.series[bat].metric)
    if args.json:
        payload = [_chart_dict(q, bat, c) for q, bat, c in shown]
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    if not shown:
        print("no check runs in this store (rig check --bat REF.toml records one)")
    for q, bat, c in shown:
        _print_chart(q, bat, c)
    return 0


def _chart_dict(q: Any, bat: str, c: Any) -> dict[str, Any]:
    open_keys = {s.key for b, s in q.unacknowledged if b == bat}
    data = c.as_dict()
    for sig in data["signals"]:
        sig["acknowledged"] = sig["key"] not in open_keys
    series = q.series[bat]
    restart = None if series.restart is None else series.restart.as_dict()
    return {
        "rig": q.rig, "bat": bat, "metric": series.metric, "state": q.state(), "restart": restart,
        "sessions_before_restart": series.earlier, **data,
    }  # fmt: skip


def _print_chart(q: Any, bat: str, c: Any) -> None:
    table = new_table(title=f"rig {q.rig}, reference bat {bat}: {q.state()}", show_header=True)
    add_columns(table, "#", "run", "phase")
    add_columns(table, "n", "mean", "s", "EWMA", "EWMA limits", "s UCL", "signal", justify="right")
    flagged: dict[int, list[str]] = {}
    for sig in c.signals:
        flagged.setdefault(sig.index, []).append(sig.rule)

    def num(v: float | None, digits: int = 5) -> str:
        return "-" if v is None else f"{v:.{digits}f}"

    for p in c.points:
        limits = "-" if p.ewma_low is None else f"{p.ewma_low:.5f} - {p.ewma_high:.5f}"
        table.add_row(
            str(p.index), p.session[:12], "I" if p.phase == 1 else "II", str(p.n), num(p.mean), num(p.s),
            num(p.ewma), limits, num(p.s_high), ", ".join(flagged.get(p.index, [])),
        )  # fmt: skip
    out().print(table)
    lim = c.limits()
    if lim is None:
        print(f"  phase I: {c.sessions} of {c.phase_i} sessions; no limits yet")
    else:
        print(
            f"  phase I: the first {c.phase_i} sessions; centre {lim['centre']:.5f}, sigma {c.sigma:.5f} "
            f"(moving range / 1.128), warning {lim['warning_low']:.5f} - {lim['warning_high']:.5f}, "
            f"action {lim['action_low']:.5f} - {lim['action_high']:.5f}; EWMA lambda {c.lam:g}, k {c.k:g} "
            f"(exact limits); s-chart sigma_w {num(c.sigma_within)} (mean s / c4)"
        )
    restart = q.series[bat].restart
    if restart is not None:
        print(f"  {restart.describe()}; {q.series[bat].earlier} earlier session(s) not charted")
    for note in c.notes:
        print(f"  note: {note}")
    open_keys = {s.key for b, s in q.unacknowledged if b == bat}
    for sig in c.signals:
        print(
            f"  signal: {sig.describe()} ({'NOT acknowledged' if sig.key in open_keys else 'acknowledged'})"
        )


def _crosscheck_chart(args: argparse.Namespace, plot: Any) -> int:
    """rig check chart --crosscheck: the model cross-check's standardised residuals of the certified
    runs, per bat model and calibration, on the individuals and EWMA charts (standard values 0, 1)."""
    from rig.quality.crosscheck import residual_series

    if args.bat is not None:
        raise ConfigError(
            "--bat names a reference bat; with --crosscheck give --model SERIES", source="--bat"
        )
    with open_db(args, readonly=True) as store:
        series, notes = residual_series(store, args.rig)
    shown = [s for s in series if args.model is None or s.key.startswith(args.model) or s.model == args.model]
    if args.model is not None and not shown:
        named = "; ".join(s.key for s in series) or "none"
        raise ConfigError(f"no cross-check series {args.model!r} (series: {named})", source="--model")
    if plot is not None:
        if len(shown) != 1:
            raise ConfigError(
                f"--plot draws one series; {len(shown)} match: give --model (a series' name, or its start)",
                source="--plot",
            )
        from rig.report.quality_plots import plot_charts

        only = shown[0]
        plot_charts(only.charts, f"model cross-check: {only.key}", plot, "z", unit="certified run")
    if args.json:
        payload = {"series": [s.as_dict() for s in shown], "notes": notes}
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    if not shown:
        print("no certified run with a calibrated model cross-check in this store")
    for s in shown:
        _print_residuals(s)
    for note in notes:
        print(f"note: {note}")
    return 0


def _print_residuals(s: Any) -> None:
    from rig.quality.crosscheck import NO_MODEL

    c = s.charts
    table = new_table(title=f"model cross-check, {s.key}: {len(c.signals)} signal(s)", show_header=True)
    add_columns(table, "#", "run", "bat", "rig")
    add_columns(table, "z", "EWMA", "EWMA limits", "signal", justify="right")
    flagged: dict[int, list[str]] = {}
    for sig in c.signals:
        flagged.setdefault(sig.index, []).append(sig.rule)
    for p, r in zip(c.points, s.residuals, strict=True):
        limits = f"{p.ewma_low:.3f} - {p.ewma_high:.3f}"
        table.add_row(
            str(p.index), r.run_id[:12], r.bat_id, r.rig, f"{r.z:.3f}", f"{p.ewma:.3f}", limits,
            ", ".join(flagged.get(p.index, [])),
        )  # fmt: skip
    out().print(table)
    sigma = s.observed_sigma()
    print(
        f"  z = (measured - predicted) / u, u the prediction's combined standard uncertainty; standard "
        f"values: centre 0, sigma 1, action +-3, warning +-2, EWMA lambda {c.lam:g}, k {c.k:g} (exact "
        f"limits), no phase I; the residuals' own sigma (moving range / 1.128): "
        f"{'-' if sigma is None else f'{sigma:.2f}'}"
    )
    grouped = f"bat model {s.model}" if s.model else NO_MODEL
    print(f"  calibration {s.calibration} ({s.calibration_path}); {grouped}")
    for sig in c.signals:
        print(f"  signal: {s.describe(sig)} (shown, does not block certification: investigate)")


def cmd_ack(args: argparse.Namespace) -> int:
    """rig check ack: record (lab-level, hash-chained) that NAME acknowledges a rig's open control-chart
    signals, and why; certification on that rig is allowed again until a check run signals anew."""
    from rig.quality.records import acknowledge, check_series

    signoff = signoff_from(args, "rig check ack")
    args.create_db = False
    with open_db(args) as store:
        rig = args.rig
        if rig is None:
            rigs = sorted({s.rig for s in check_series(store)[0]})
            open_rigs = [r for r in rigs if _quality(store, r, args).unacknowledged]
            if len(open_rigs) != 1:
                named = ", ".join(open_rigs) or "none"
                raise ConfigError(f"give --rig NAME (rigs with open signals: {named})", source="command line")
            rig = open_rigs[0]
        quality = _quality(store, rig, args)
        if not quality.unacknowledged:
            raise ConfigError(f"rig {rig} has no open control-chart signal to acknowledge", source="--rig")
        entry = acknowledge(store, quality, **signoff.as_dict())
    n = len(quality.unacknowledged)
    print(f"rig {rig}: {n} signal(s) acknowledged by {signoff.who} (seq {entry.seq})")
    return 0


def cmd_restart(args: argparse.Namespace) -> int:
    """rig check restart: record (lab-level, hash-chained) that NAME starts a new phase I for a rig and
    reference bat after a corrective action, and why; the charts and the gate on certification then
    use only the check runs made after it (the first 20 of them are the new phase I)."""
    from rig.quality.records import check_series, restart

    signoff = signoff_from(args, "rig check restart")
    args.create_db = False
    with open_db(args) as store:
        series = [
            s for s in check_series(store)[0] if args.rig in (None, s.rig) and args.bat in (None, s.bat)
        ]
        if len(series) != 1:
            named = ", ".join(f"--rig {s.rig} --bat {s.bat}" for s in series) or "none"
            raise ConfigError(
                f"give the rig and reference bat to restart ({len(series)} series of check runs match: "
                f"{named})",
                source="command line",
            )
        entry = restart(store, series[0], **signoff.as_dict())
    print(
        f"rig {series[0].rig}, reference bat {series[0].bat}: new phase I from the next check run, recorded "
        f"by {signoff.who} (seq {entry.seq}); {len(series[0].sessions)} earlier session(s) no longer charted"
    )
    return 0


def add_parsers(sub: Any) -> None:
    """`rig check ...`."""
    check = sub.add_parser(
        "check",
        help="the check standard: a check session on the reference bat, its control charts, acknowledgements",
        description=cmd_check.__doc__,
    )
    check.add_argument("--bat", metavar="REF.toml", help="the reference bat's file")
    check.add_argument(
        "--procedure", metavar="FILE", help="the lab's check procedure (default protocols/check.toml)"
    )
    check.add_argument(
        "--hits", type=positive_int, metavar="N", help="hits in the session (default the procedure's)"
    )
    add_rig_options(check)
    check.add_argument("--db", metavar="FILE", help=DB_HELP)
    check.add_argument("--json", action="store_true", help="print the session and the rig's state as JSON")
    check.set_defaults(handler=cmd_check, phase_i=None)
    csub = check.add_subparsers(dest="check_command", required=False, metavar="CHECK_COMMAND")

    p = csub.add_parser("chart", help="the control charts and their signals", description=cmd_chart.__doc__)
    p.add_argument("--rig", metavar="NAME", help="one rig (default: every rig with check runs)")
    p.add_argument("--bat", metavar="ID", help="one reference bat (its id)")
    p.add_argument("--plot", metavar="FILE", help="draw the three charts (PNG and SVG)")
    p.add_argument(
        "--phase-i", type=positive_int, default=20, metavar="M", help="sessions in phase I (default 20)"
    )
    p.add_argument(
        "--crosscheck",
        action="store_true",
        help="the model cross-check's residuals of the certified runs, per bat model and calibration",
    )
    p.add_argument("--model", metavar="SERIES", help="with --crosscheck: one series (its name, or its start)")
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_chart)

    p = csub.add_parser(
        "ack", help="acknowledge a rig's open signals (recorded)", description=cmd_ack.__doc__
    )
    p.add_argument("--rig", metavar="NAME", help="the rig (default: the only one with open signals)")
    p.add_argument("--who", metavar="NAME", help="who acknowledges (recorded)")
    p.add_argument("--why", metavar="TEXT", help="why: the cause found and what was done (recorded)")
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.set_defaults(handler=cmd_ack)

    p = csub.add_parser(
        "restart",
        help="start a new phase I for a rig and reference bat after a corrective action (recorded)",
        description=cmd_restart.__doc__,
    )
    p.add_argument("--rig", metavar="NAME", help="the rig (default: the only one with check runs)")
    p.add_argument("--bat", metavar="ID", help="the reference bat (default: the rig's only one)")
    p.add_argument("--who", metavar="NAME", help="who restarts (recorded)")
    p.add_argument("--why", metavar="TEXT", help="why: the corrective action (recorded)")
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    p.set_defaults(handler=cmd_restart)
