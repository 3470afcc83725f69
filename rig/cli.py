"""The `rig` command line: a thin client over the controller's functions.

Every command has --help. Errors print one line naming the cause and exit with status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rig.core.errors import ConfigError, ParameterError, RigError

Handler = Callable[[argparse.Namespace], int]


def _param_override(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name.strip()}: {value!r} is not a number") from None


def _model_parent() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument(
        "--set",
        dest="overrides",
        metavar="NAME=VALUE",
        type=_param_override,
        action="append",
        default=[],
        help="override a model constant (m1, k1, c1, a, b, m2, c2), e.g. --set m2=0.1",
    )
    parent.add_argument("--rtol", type=float, default=None, help="solver relative tolerance")
    parent.add_argument("--json", action="store_true", help="print JSON instead of a table")
    return parent


def _params(args: argparse.Namespace) -> Any:
    from rig.physics.params import CollisionParams

    return CollisionParams.build(**dict(args.overrides))


def _emit(args: argparse.Namespace, payload: dict[str, Any], title: str) -> None:
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


def _rtol(args: argparse.Namespace, default: float) -> float:
    return default if args.rtol is None else args.rtol


def cmd_cor(args: argparse.Namespace) -> int:
    """rig model cor: COR of one ball-barrel collision."""
    from rig.physics import fast
    from rig.physics.curve import rigid_cor
    from rig.physics.equations import Impact

    params = _params(args)
    rtol = _rtol(args, fast.DEFAULT_RTOL)
    hoop = None if args.rigid else args.hoop
    res = fast.solve(Impact(params, args.speed, hoop), rtol=rtol)
    e_rigid = res.cor if hoop is None else rigid_cor(params, args.speed)
    payload = {
        "speed_m_s": args.speed,
        "hoop_hz": hoop,
        "model": "rigid" if hoop is None else "barrel",
        "cor": res.cor,
        "cor_rigid": e_rigid,
        "efficiency": res.cor / e_rigid,
        "contact_time_s": res.contact_time_s,
        "rtol": rtol,
        "nfev": res.nfev,
        "params": params.model_dump(),
    }
    _emit(args, payload, "Ball-barrel collision")
    return 0


def cmd_curve(args: argparse.Namespace) -> int:
    """rig model curve: normalized collision efficiency against hoop frequency."""
    from rig.physics import fast
    from rig.physics.curve import efficiency_curve

    params = _params(args)
    curve = efficiency_curve(
        params, args.speed, args.hoop_min, args.hoop_max, args.points, rtol=_rtol(args, fast.DEFAULT_RTOL)
    )
    if args.plot:
        from rig.report.model_plots import plot_efficiency_curve

        for path in plot_efficiency_curve(curve, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    payload = {
        "speed_m_s": curve.speed,
        "cor_rigid": curve.cor_rigid,
        "optimum_hz": curve.optimum_hz,
        "optimum_efficiency": curve.optimum_efficiency,
        "optimum_interior": curve.optimum_interior,
        "rtol": curve.rtol,
        "hoop_hz": curve.hoop_hz.tolist(),
        "efficiency": curve.efficiency.tolist(),
        "cor": curve.cor.tolist(),
        "contact_time_s": curve.contact_time_s.tolist(),
    }
    if args.json:
        _emit(args, payload, "")
    else:
        _print_curve(curve)
    return 0


def _print_curve(curve: Any, rows: int = 16) -> None:
    """A readable digest of the curve: a sample of the grid with a bar per point, and the optimum."""
    from rich.console import Console
    from rich.table import Table

    idx = sorted(
        set(np.linspace(0, curve.hoop_hz.size - 1, min(rows, curve.hoop_hz.size)).round().astype(int))
    )
    lo, hi = float(curve.efficiency.min()), float(curve.efficiency.max())
    table = Table(
        title=f"Normalized collision efficiency at {curve.speed:g} m/s (COR_rigid = {curve.cor_rigid:.4f})"
    )
    for col in ("hoop Hz", "COR", "eta", ""):
        table.add_column(col, justify="right" if col else "left")
    for i in idx:
        eta = float(curve.efficiency[i])
        bar = "#" * (1 + int(30 * (eta - lo) / (hi - lo or 1.0)))
        table.add_row(f"{curve.hoop_hz[i]:.0f}", f"{curve.cor[i]:.4f}", f"{eta:.4f}", bar)
    console = Console()
    console.print(table)
    where = "between grid points" if curve.optimum_interior else "at the end of the grid"
    console.print(
        f"optimum: {curve.optimum_hz:.1f} Hz, eta = {curve.optimum_efficiency:.4f} ({where}); "
        f"{curve.hoop_hz.size} points, rtol {curve.rtol:g}"
    )


def cmd_bat(args: argparse.Namespace) -> int:
    """rig model bat: e_A and BBCOR predicted for a bat on the pivot."""
    from rig.physics import fast
    from rig.physics.bat import PivotedBat, predict_bat

    params = _params(args)
    bat = PivotedBat.build(moi_kgm2=args.moi, impact_from_pivot_m=args.impact_from_pivot)
    hoop = None if args.rigid else args.hoop
    pred = predict_bat(params, args.speed, hoop, bat, rtol=_rtol(args, fast.DEFAULT_RTOL))
    payload = {
        "speed_m_s": pred.speed,
        "hoop_hz": pred.hoop_hz,
        "moi_kgm2": bat.moi_kgm2,
        "impact_from_pivot_m": bat.impact_from_pivot_m,
        "e_a": pred.e_a,
        "bbcor": pred.bbcor,
        "besr": pred.besr,
        "k": pred.k,
        "effective_mass_kg": pred.effective_mass_kg,
        "contact_time_s": pred.contact_time_s,
        "definitions": {
            "e_a": "rebound speed / inbound speed, bat initially at rest",
            "bbcor": "e_a (1 + k) + k, k = m_ball Q^2 / I (founding paper Eq. 5)",
            "besr": "e_a + 1/2",
        },
    }
    _emit(args, payload, "Pivoted-bat prediction")
    return 0


def cmd_accuracy(args: argparse.Namespace) -> int:
    """rig model accuracy: the work-precision study of the collision solvers."""
    from rig.physics.precision import work_precision

    study = work_precision(quick=args.quick, repeats=args.repeats)
    if args.plot:
        from rig.report.precision_plots import plot_work_precision

        for path in plot_work_precision(study, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        json.dump([row.as_dict() for row in study.rows], sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        from rich.console import Console

        from rig.report.precision_plots import precision_table

        Console().print(precision_table(study))
    return 0


def _rig_config(args: argparse.Namespace) -> Any:
    """The rig config from --sim, --config or the three port URLs."""
    from rig.core.config import RigConfig
    from rig.core.errors import ConfigError

    if args.sim is not None:
        from rig.session import sim_config

        return sim_config(args.sim)
    if args.config:
        return RigConfig.load(args.config)
    ports = {"cannon": args.cannon, "gates": args.gates, "clamp": args.clamp}
    missing = [f"--{k}" for k, v in ports.items() if not v]
    if missing:
        raise ConfigError(f"give --sim [SCENE], --config RIG.toml, or all of {', '.join(missing)}")
    return RigConfig.from_dict({"ports": ports}, source="command line")


def cmd_shot(args: argparse.Namespace) -> int:
    """rig shot: fire one shot through the drivers and print the raw and derived figures."""
    from protocols.shot import ShotFailed, fire_shot, prepare
    from rig.session import RigSession

    config = _rig_config(args)
    if args.impact_from_pivot is not None:
        config = config.model_copy(update={"impact_from_pivot_m": args.impact_from_pivot})
    with RigSession.open(config) as session:
        cfg = prepare(session.cannon, session.gates, session.clamp, config.impact_from_pivot_m)
        try:
            record = fire_shot(session.cannon, session.gates, session.clamp, config, args.speed, cfg)
        except ShotFailed as exc:
            if exc.record is not None and args.json:
                json.dump({"error": str(exc), **exc.record.as_dict()}, sys.stderr, allow_nan=False)
                sys.stderr.write("\n")
            raise
    payload = record.as_dict()
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        shown = {k: v for k, v in payload.items() if k not in ("crossings", "extra_crossings")}
        shown["crossings"] = " ".join(f"G{c['gate']}@{c['tick']}" for c in payload["crossings"])
        args.json = False
        _emit(args, shown, f"Shot {record.shot_number}")
    return 0


def cmd_sim_serve(args: argparse.Namespace) -> int:
    """rig sim serve: expose the simulated devices on ptys or TCP ports until interrupted."""
    from simulators.scene import Scene
    from simulators.serve import serve

    serve(Scene.load(args.scene), kind=args.kind, base_port=args.base_port)
    return 0


def _db(args: argparse.Namespace) -> Any:
    from rig.certification import default_db
    from rig.store import Store

    return Store.open(args.db or default_db(), create=getattr(args, "create_db", False))


def _resolve_run(store: Any, text: str) -> str:
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


def cmd_certify(args: argparse.Namespace) -> int:
    """rig certify: run a certification procedure on a bat, live, recording everything."""
    from protocols.procedure import Procedure
    from protocols.runner import ScriptedOperator, dry_run
    from rig.certification import certify
    from rig.core.bat import BatSpec
    from rig.core.config import RigConfig
    from rig.report.live import LiveConsole
    from rig.report.record import run_record

    args.create_db = True
    with _db(args) as store:
        if args.resume:
            run_id = _resolve_run(store, args.resume)
            started = store.entries(run_id, kinds=["RunStarted"])
            if not started:
                raise ConfigError(f"run {run_id} never started; start a new one", source="--resume")
            payload = started[0].payload
            procedure = Procedure.model_validate(payload["procedure"])
            bat = BatSpec.model_validate(payload["bat"])
        else:
            if not args.procedure or not args.bat:
                raise ConfigError("give --procedure and --bat (or --resume RUN)", source="command line")
            procedure, bat = Procedure.load(args.procedure), BatSpec.load(args.bat)
            from rig.modal.link import with_measured_hoop

            bat = with_measured_hoop(store, bat)  # hoop_hz from the bat's linked modal result, if any
            run_id = None
        if args.sim is not None:
            from rig.session import sim_config

            config = sim_config(args.sim, bat=bat)
        elif args.config:
            config = RigConfig.load(args.config)
        else:
            raise ConfigError("give --sim [SCENE] or --config RIG.toml", source="command line")
        problems = dry_run(procedure, bat, config)
        if problems or args.dry_run:
            for line in problems or ["dry run: the procedure fits this rig and this bat"]:
                print(line, file=sys.stderr)
            if problems:
                raise ConfigError("; ".join(problems), source="dry run")
            return 0
        live = LiveConsole(quiet=args.json)
        outcome = certify(
            store,
            procedure,
            bat,
            config,
            run_id=run_id,
            operator=ScriptedOperator(who="script (--sim or scripted run)"),
            subscribers=[live],
        )
        live.close()
        if args.json:
            json.dump(run_record(store, outcome.run_id), sys.stdout, indent=2, allow_nan=False)
            sys.stdout.write("\n")
        else:
            live.summary(outcome)
    if outcome.status != "finished":
        print(
            f"rig: run {outcome.run_id} interrupted: {outcome.reason}; "
            f"resume with: rig certify --resume {outcome.run_id}",
            file=sys.stderr,
        )
        return 3
    return 0 if outcome.verdict and outcome.verdict.get("verdict") == "PASS" else 1


def cmd_runs(args: argparse.Namespace) -> int:
    """rig runs: the recorded runs, newest last."""
    from rich.console import Console
    from rich.table import Table

    with _db(args) as store:
        runs = store.runs()
    if args.json:
        json.dump([r.__dict__ for r in runs], sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    table = Table(title=f"Runs in {args.db or 'rig-records.db'}")
    for col in ("run", "procedure", "bat", "started (UTC)", "status", "verdict"):
        table.add_column(col)
    for r in runs:
        table.add_row(r.run_id[:12], r.procedure, r.bat_id, r.started_utc[:19], r.status, r.verdict or "")
    Console().print(table)
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """rig report: a run's record as JSON, or its certificate as Markdown or HTML."""
    from rig.report.record import run_record

    with _db(args) as store:
        record = run_record(store, _resolve_run(store, args.run))
    if args.format == "json":
        text = json.dumps(record, indent=2, allow_nan=False) + "\n"
    else:
        from rig.report.certificate import render

        text = render(record, args.format, figures_dir=args.figures, output=args.output)
    if args.output:
        Path(args.output).parent.mkdir(parents=True, exist_ok=True)
        Path(args.output).write_text(text, encoding="utf-8")
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0


def cmd_tui(args: argparse.Namespace) -> int:
    """rig tui: the operator's console (set-up, live run, history) in the terminal."""
    from rig.certification import default_db
    from rig.tui import ConsoleSettings, RigConsole

    if args.sim is None and not args.config:
        raise ConfigError("give --sim [SCENE] or --config RIG.toml", source="command line")
    settings = ConsoleSettings.from_args(
        args.sim, args.config, args.db or default_db(), bat=args.bat or "", procedure=args.procedure or ""
    )
    RigConsole(settings).run()
    return 0


def cmd_verify(args: argparse.Namespace) -> int:
    """rig verify: recompute the hash chain; non-zero exit if any record was altered."""
    from rig.store import Anchor

    anchors = []
    if args.anchor:
        seq, _, digest = args.anchor.partition(":")
        anchors.append(Anchor(int(seq), digest))
    with _db(args) as store:
        report = store.verify(anchors)
    if report.ok:
        print(
            f"ok: {report.entries_checked} entries, chain intact; head {report.head.seq}:{report.head.hash}"
        )
        return 0
    print(f"ALTERED: first broken entry {report.first_broken_seq}: {report.reason}")
    for problem in report.problems:
        print(f"  {problem}")
    return 1


def _modal_settings(args: argparse.Namespace) -> Any:
    from rig.modal import ModalSettings

    given = {
        "window_s": args.window,
        "max_resolution_hz": args.max_resolution,
        "min_coherence": args.min_coherence,
    }
    return ModalSettings(**{k: v for k, v in given.items() if v is not None})


def cmd_modal_analyze(args: argparse.Namespace) -> int:
    """rig modal analyze: hoop and bending frequencies from an impact test (CSV or UFF recording)."""
    from rig.modal import analyze, read_recording

    if args.db and not args.bat:
        raise ConfigError("--db records the result for a bat: give --bat BAT.toml too", source="command line")
    result = analyze(read_recording(args.file), _modal_settings(args))
    payload = result.as_dict()
    if args.plot:
        from rig.report.modal_plots import plot_modal

        for path in plot_modal(result, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    if args.bat:
        from rig.certification import default_db
        from rig.core.bat import BatSpec
        from rig.modal import record_modal_result

        bat = BatSpec.load(args.bat)
        args.create_db = True
        with _db(args) as store:
            linked = record_modal_result(store, bat.id, result, args.file)
        payload["linked"] = {"bat_id": bat.id, "db": str(args.db or default_db()), "sha256": linked["sha256"]}
        print(f"recorded the modal result for bat {bat.id} in {payload['linked']['db']}", file=sys.stderr)
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"Modes of {args.file} ({result.n_hits} hits, resolution {result.resolution_hz:.3g} Hz)"
    )
    for col in ("kind", "f (Hz)", "U (Hz, k=2)", "damping", "|H1|/|H2|", "coherence"):
        table.add_column(col, justify="left" if col == "kind" else "right")
    for m in result.modes:
        table.add_row(
            m.kind,
            f"{m.frequency_hz:.1f}",
            f"{m.expanded_uncertainty_hz:.2g}",
            f"{m.damping_ratio:.4f}",
            f"{m.magnitude_ratio:.3g}",
            f"{m.coherence:.3f}",
        )
    console = Console()
    console.print(table)
    hoop = result.hoop
    console.print(
        "first hoop frequency: "
        + (
            "none found"
            if hoop is None
            else f"{hoop.frequency_hz:.1f} ± {hoop.expanded_uncertainty_hz:.2g} Hz (k=2)"
        )
    )
    console.print("bending: " + (", ".join(f"{f:.1f}" for f in result.bending_hz) or "none") + " Hz")
    for w in result.warnings:
        console.print(f"note: {w}")
    return 0


def cmd_modal_simulate(args: argparse.Namespace) -> int:
    """rig modal simulate: write a simulated impact-test recording (CSV, or UFF for .uff/.unv)."""
    from rig.modal import SimSettings, bat_modes, simulate, write_csv
    from rig.modal.uff import write_uff

    hoops: float | tuple[float, ...] = 1800.0 if not args.hoop else tuple(args.hoop)
    if isinstance(hoops, tuple) and len(hoops) == 1:
        hoops = hoops[0]  # one hoop frequency: bat_modes adds the second hoop mode
    settings = SimSettings(
        hits=args.hits,
        hit_interval_s=args.interval,
        noise=args.noise,
        seed=args.seed,
        double_hit=None if args.double_hit is None else args.double_hit - 1,
        clip_force=args.clip_force,
        modes=bat_modes(hoops, bending_hz=args.bending),
    )
    rec = simulate(settings)
    truth = ", ".join(f"{m.kind} {m.frequency_hz:g} Hz" for m in settings.modes)
    if Path(args.out).suffix.lower() in (".uff", ".unv"):
        path = write_uff(rec, args.out)
    else:
        path = write_csv(rec, args.out, [f"simulated modal test (rig modal simulate): {truth}"])
    print(
        f"wrote {path}: {settings.hits} hits, {rec.duration_s:.3g} s at {rec.fs:g} Hz; modes: {truth}",
        file=sys.stderr,
    )
    return 0


def cmd_study(args: argparse.Namespace) -> int:
    """rig study: the population study, hoop frequency against bending and performance (paper section 5)."""
    from rig.population import load_population, run_study

    bats, sources, notes = [], [], []
    data = args.data
    if not data and not args.db:
        data = [str(Path(__file__).resolve().parents[1] / "protocols" / "examples" / "population.csv")]
        print("rig: no --data or --db: using the SYNTHETIC sample population", file=sys.stderr)
    for path in data or []:
        bats += load_population(path)
        sources.append(str(path))
    if args.db:
        from rig.population.store_source import bats_from_store

        with _db(args) as store:
            stored, why = bats_from_store(store)
        bats += stored
        notes += why
        sources.append(str(args.db))
    ids = [b.bat_id for b in bats]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ConfigError(f"bat id(s) in more than one source: {', '.join(twice)}", source="rig study")
    if not bats:
        raise ConfigError("no bats with a hoop frequency in the given sources", source="rig study")
    study = run_study(bats, sources, notes)
    if args.plot_dir:
        from rig.report.population_plots import plot_population

        for path in plot_population(study, args.plot_dir):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        json.dump(study.as_dict(), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    from rich.console import Console
    from rich.table import Table

    console = Console()
    tag = " (SYNTHETIC sample data)" if study.synthetic else ""
    table = Table(title=f"Fig. 6: 50 Hz bins averaged over ±25 Hz, {len(study.bats)} bats{tag}")
    for col in ("hoop Hz", "n", "BESR", "BBS (m/s)", "BBCOR"):
        table.add_column(col, justify="right")
    by_centre: dict[float, dict[str, Any]] = {}
    for name, bins in study.bins.items():
        for b in bins:
            by_centre.setdefault(b.center_hz, {"n": b.n})[name] = b.mean
    for centre in sorted(by_centre):
        row = by_centre[centre]
        cells = [f"{row[m]:.4g}" if m in row else "" for m in ("besr", "bbs", "bbcor")]
        table.add_row(f"{centre:.0f}", str(row["n"]), *cells)
    console.print(table)
    for material, d in study.materials().items():
        console.print(f"{material}: {d['n']} bats, hoop {d['hoop_min_hz']:.0f}-{d['hoop_max_hz']:.0f} Hz")
    for name, t in study.trend.items():
        if t.get("slope_per_khz") is not None:
            console.print(
                f"{name}: {t['slope_per_khz']:+.4g} per 1000 Hz"
                f" (model {t.get('model_slope_per_khz', 0.0):+.4g}), r = {t['r']:.3f}"
            )
    for note in study.notes:
        console.print(f"note: {note}")
    return 0


def _add_modal_parsers(sub: Any) -> None:
    """`rig modal analyze|simulate` and `rig study`."""
    modal = sub.add_parser("modal", help="modal analysis of impact tests (hoop frequency)")
    msub = modal.add_subparsers(dest="modal_command", required=True, metavar="MODAL_COMMAND")
    p = msub.add_parser(
        "analyze", help="hoop and bending modes of a recording", description=cmd_modal_analyze.__doc__
    )
    p.add_argument(
        "file", metavar="FILE", help="recording: .csv (time_s,force_N,accel1_ms2,accel2_ms2) or .uff"
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--plot", metavar="FILE", help="plot FRFs, coherence and modes (PNG and SVG)")
    p.add_argument("--bat", metavar="BAT.toml", help="record the result for this bat in the store")
    p.add_argument("--db", metavar="FILE", help="record store for --bat (default rig-records.db)")
    p.add_argument(
        "--window", type=float, metavar="S", help="analysis window per hit, s (default: automatic)"
    )
    p.add_argument(
        "--max-resolution", type=float, metavar="HZ", help="refuse windows coarser than this (20 Hz)"
    )
    p.add_argument("--min-coherence", type=float, metavar="X", help="least coherence at the hoop mode (0.9)")
    p.set_defaults(handler=cmd_modal_analyze)

    p = msub.add_parser(
        "simulate", help="write a simulated impact test", description=cmd_modal_simulate.__doc__
    )
    p.add_argument("out", metavar="OUT", help="output file: .csv, or .uff/.unv")
    p.add_argument(
        "--hoop", type=float, nargs="+", metavar="HZ", help="hoop frequencies (default 1800 and 1.7x)"
    )
    p.add_argument("--bending", type=float, default=175.0, metavar="HZ", help="first bending frequency")
    p.add_argument("--hits", type=_positive_int, default=5, help="number of hits")
    p.add_argument("--interval", type=float, default=0.5, metavar="S", help="time between hits, s")
    p.add_argument("--noise", type=float, default=1e-3, help="noise std as a fraction of each channel's peak")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--double-hit", type=_positive_int, metavar="N", help="make hit N a double hit (a fault)")
    p.add_argument(
        "--clip-force", type=float, metavar="FRACTION", help="clip the force at this fraction (a fault)"
    )
    p.set_defaults(handler=cmd_modal_simulate)

    p = sub.add_parser(
        "study", help="population study: hoop frequency vs performance", description=cmd_study.__doc__
    )
    p.add_argument(
        "--data", action="append", metavar="FILE", help="population file (.csv or .toml); repeatable"
    )
    p.add_argument("--db", metavar="FILE", help="also the bats of this record store")
    p.add_argument("--plot-dir", metavar="DIR", help="write Fig. 5 and Fig. 6 (PNG and SVG) here")
    p.add_argument("--json", action="store_true", help="print the study as JSON")
    p.set_defaults(handler=cmd_study)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The whole command tree."""
    parser = argparse.ArgumentParser(prog="rig", description="Bat-certification rig controller.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    model = sub.add_parser("model", help="the ball-barrel collision model", description=__doc__)
    msub = model.add_subparsers(dest="model_command", required=True, metavar="MODEL_COMMAND")
    parent = _model_parent()

    p = msub.add_parser("cor", parents=[parent], help="COR of one collision")
    p.add_argument("--speed", type=float, required=True, help="inbound ball speed, m/s")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--hoop", type=float, help="hoop frequency of the barrel, Hz")
    g.add_argument("--rigid", action="store_true", help="a rigid barrel (f_hoop -> infinity)")
    p.set_defaults(handler=cmd_cor)

    p = msub.add_parser("curve", parents=[parent], help="efficiency eta(f) = COR(f)/COR_rigid")
    p.add_argument("--speed", type=float, required=True, help="inbound ball speed, m/s")
    p.add_argument("--hoop-min", type=float, required=True, help="lowest hoop frequency, Hz")
    p.add_argument("--hoop-max", type=float, required=True, help="highest hoop frequency, Hz")
    p.add_argument("--points", type=_positive_int, default=200, help="grid points, evenly spaced")
    p.add_argument("--plot", metavar="FILE", help="write a plot (PNG and SVG beside it)")
    p.set_defaults(handler=cmd_curve)

    p = msub.add_parser("bat", parents=[parent], help="e_A and BBCOR of a bat on the pivot")
    p.add_argument("--speed", type=float, required=True, help="inbound ball speed, m/s")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--hoop", type=float, help="hoop frequency of the barrel, Hz")
    g.add_argument("--rigid", action="store_true", help="a rigid barrel (a wood bat)")
    p.add_argument("--moi", type=float, required=True, help="MOI about the pivot, kg m^2")
    p.add_argument("--impact-from-pivot", type=float, required=True, help="pivot-to-impact distance Q, m")
    p.set_defaults(handler=cmd_bat)

    p = msub.add_parser("accuracy", help="work-precision study: error against cost of each solver")
    p.add_argument("--plot", metavar="FILE", help="write the plots (PNG and SVG)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    p.add_argument("--quick", action="store_true", help="fewer tolerances and methods (a smoke run)")
    p.add_argument("--repeats", type=_positive_int, default=5, help="timed repeats (best of N)")
    p.set_defaults(handler=cmd_accuracy)

    p = sub.add_parser("shot", help="fire one shot through the drivers", description=cmd_shot.__doc__)
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--sim",
        nargs="?",
        const="ideal",
        metavar="SCENE",
        help="simulated rig: ideal (default), lab, faulty or a scene TOML file",
    )
    where.add_argument("--config", metavar="RIG.toml", help="rig configuration file")
    p.add_argument("--cannon", metavar="URL", help="cannon port URL (device path, socket://, sim://)")
    p.add_argument("--gates", metavar="URL", help="light-gate port URL")
    p.add_argument("--clamp", metavar="URL", help="pivot-clamp port URL")
    p.add_argument("--speed", type=float, required=True, help="target inbound speed, m/s")
    p.add_argument("--impact-from-pivot", type=float, help="impact point from the pivot, m")
    p.add_argument("--json", action="store_true", help="print the shot record as JSON")
    p.set_defaults(handler=cmd_shot)

    p = sub.add_parser("certify", help="certify a bat (BBCOR, BESR, BBS)", description=cmd_certify.__doc__)
    p.add_argument("--procedure", help="bbcor, besr, bbs, or a procedure TOML file")
    p.add_argument("--bat", metavar="BAT.toml", help="bat file (table [bat])")
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--sim",
        nargs="?",
        const="ideal",
        metavar="SCENE",
        help="simulated rig: ideal (default), lab, faulty or a scene TOML file",
    )
    where.add_argument("--config", metavar="RIG.toml", help="rig configuration file")
    p.add_argument("--db", metavar="FILE", help="record store (default rig-records.db)")
    p.add_argument("--resume", metavar="RUN", help="resume an interrupted run")
    p.add_argument("--dry-run", action="store_true", help="check the procedure against rig and bat only")
    p.add_argument("--json", action="store_true", help="print the run record as JSON")
    p.set_defaults(handler=cmd_certify)

    p = sub.add_parser("runs", help="list recorded runs", description=cmd_runs.__doc__)
    p.add_argument("--db", metavar="FILE", help="record store (default rig-records.db)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_runs)

    p = sub.add_parser("report", help="a run's record or certificate", description=cmd_report.__doc__)
    p.add_argument("run", metavar="RUN", help="run id (a unique prefix will do), or 'last'")
    p.add_argument("--format", choices=("json", "md", "html"), default="md", help="output format")
    p.add_argument("--db", metavar="FILE", help="record store (default rig-records.db)")
    p.add_argument("--output", "-o", metavar="FILE", help="write to a file instead of stdout")
    p.add_argument("--figures", metavar="DIR", help="where the certificate's plots go (md/html)")
    p.set_defaults(handler=cmd_report)

    p = sub.add_parser("tui", help="the operator's console (terminal UI)", description=cmd_tui.__doc__)
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--sim",
        nargs="?",
        const="ideal",
        metavar="SCENE",
        help="simulated rig: ideal (default), lab, faulty or a scene TOML file",
    )
    where.add_argument("--config", metavar="RIG.toml", help="rig configuration file")
    p.add_argument("--db", metavar="FILE", help="record store (default rig-records.db)")
    p.add_argument("--bat", metavar="BAT.toml", help="preselect this bat file")
    p.add_argument("--procedure", help="preselect bbcor, besr, bbs or a procedure TOML file")
    p.set_defaults(handler=cmd_tui)

    p = sub.add_parser("verify", help="check the records' hash chain", description=cmd_verify.__doc__)
    p.add_argument("--db", metavar="FILE", help="record store (default rig-records.db)")
    p.add_argument("--anchor", metavar="SEQ:HASH", help="a head hash printed on a certificate")
    p.set_defaults(handler=cmd_verify)

    _add_modal_parsers(sub)

    sim = sub.add_parser("sim", help="simulated hardware")
    ssub = sim.add_subparsers(dest="sim_command", required=True, metavar="SIM_COMMAND")
    p = ssub.add_parser(
        "serve", help="expose simulated devices out of process", description=cmd_sim_serve.__doc__
    )
    p.add_argument("--scene", default="ideal", help="ideal, lab, faulty or a scene TOML file")
    p.add_argument("--kind", choices=("pty", "tcp"), default="pty", help="pty (default) or tcp on 127.0.0.1")
    p.add_argument("--base-port", type=int, default=0, help="first TCP port (default: any free port)")
    p.set_defaults(handler=cmd_sim_serve)
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


if __name__ == "__main__":
    raise SystemExit(main())
