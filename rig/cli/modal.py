"""`rig modal analyze|simulate` and `rig study`: hoop frequency from impact tests, the population."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rig.cli.common import (
    Bounds,
    ConfigError,
    check_flags,
    default_db,
    new_table,
    open_db,
    output_dir,
    output_file,
    positive_int,
)
from rig.cli.common import console as out
from rig.core.dbpath import DB_HELP

# Physical ranges of the flags (docs/procedures.md, "Bounds"). A bat's hoop modes ring at 200-10000
# Hz (as a bat file bounds them) and its first bending mode near 150-200 Hz (20-5000 Hz allowed); an
# analysis window of 10 ms-10 s (resolution 100-0.1 Hz); at most 100 hits of 0.05-10 s each, so a
# simulated recording stays under 1000 s (about 400 MB at 51.2 kHz would be the most).
BOUNDS: Bounds = {
    "window": ("window", 0.01, 10.0, "s"),
    "max_resolution": ("max_resolution", 0.1, 1000.0, "Hz"),
    "min_coherence": ("min_coherence", 0.0, 1.0, ""),
    "band_min": ("band_min", 1.0, 50000.0, "Hz"),
    "band_max": ("band_max", 1.0, 50000.0, "Hz"),
    "hoop": ("hoop", 200.0, 10000.0, "Hz"),
    "bending": ("bending", 20.0, 5000.0, "Hz"),
    "hits": ("hits", 1, 100, ""),
    "interval": ("interval", 0.05, 10.0, "s"),
    "noise": ("noise", 0.0, 1.0, "of the peak"),
    "seed": ("seed", 0, 2**32 - 1, ""),
    "double_hit": ("double_hit", 1, 100, ""),
    "clip_force": ("clip_force", 0.0, 1.0, "of the peak"),
}


def _modal_settings(args: argparse.Namespace) -> Any:
    from rig.modal import ModalSettings

    given = {
        "window_s": args.window,
        "max_resolution_hz": args.max_resolution,
        "min_coherence": args.min_coherence,
        "f_min_hz": args.band_min,
        "f_max_hz": args.band_max,
    }
    return ModalSettings(**{k: v for k, v in given.items() if v is not None})


def cmd_modal_analyze(args: argparse.Namespace) -> int:
    """rig modal analyze: hoop and bending frequencies from an impact test (CSV or UFF recording)."""
    from rig.modal import analyze, read_recording

    check_flags(args, BOUNDS)
    output_file(args.plot, "--plot")
    if args.db and not args.bat:
        raise ConfigError("--db records the result for a bat: give --bat BAT.toml too", source="command line")
    bat = None
    if args.bat:  # a bad bat file is refused before the analysis and the plots
        from rig.core.bat import BatSpec

        bat = BatSpec.load(args.bat)
        if Path(args.file).exists() and not Path(args.file).is_file():
            raise ConfigError("--bat records the file's sha256: give a regular file", source=args.file)
    result = analyze(read_recording(args.file), _modal_settings(args))
    payload = result.as_dict()
    if args.plot:
        from rig.report.modal_plots import plot_modal

        for path in plot_modal(result, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    if bat is not None:
        from rig.modal import record_modal_result

        args.create_db = True
        with open_db(args) as store:
            linked = record_modal_result(store, bat.id, result, args.file)
        payload["linked"] = {
            "bat_id": bat.id,
            "db": str(args.db or default_db()),
            "sha256": linked["sha256"],
        }
        print(f"recorded the modal result for bat {bat.id} in {payload['linked']['db']}", file=sys.stderr)
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    table = new_table(
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
    console = out()
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
    bending = ", ".join(f"{f:.1f}" for f in result.bending_hz)
    console.print(f"bending: {bending} Hz" if bending else "bending: none found")
    for w in result.warnings:
        console.print(f"note: {w}")
    return 0


def cmd_modal_simulate(args: argparse.Namespace) -> int:
    """rig modal simulate: write a simulated impact-test recording (CSV, or UFF for .uff/.unv)."""
    from rig.modal import SimSettings, bat_modes, simulate, write_csv
    from rig.modal.uff import write_uff

    check_flags(args, BOUNDS)
    output_file(args.out, "OUT")
    if args.double_hit is not None and args.double_hit > args.hits:
        raise ConfigError(
            f"--double-hit {args.double_hit} is beyond --hits {args.hits}", source="command line"
        )
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
    from rig.cli.study_certify import check_args
    from rig.measure.registry import heading
    from rig.population import METRICS, load_population, run_study

    check_args(args)
    output_dir(args.plot_dir, "--plot-dir")
    if args.certify is not None:
        from rig.cli.study_certify import run as certify_population

        code = certify_population(args)
        if code or not (args.json or args.plot_dir or args.calibration):
            return code
    bats, sources, notes = [], [], []
    data = args.data
    if not data and not args.db:
        import rig.protocols

        data = [str(Path(rig.protocols.__file__).parent / "examples" / "population.csv")]
        print("rig: no --data or --db: using the SYNTHETIC sample population", file=sys.stderr)
    for path in data or []:
        bats += load_population(path)
        sources.append(str(path))
    if args.db:
        from rig.population.store_source import bats_from_store

        with open_db(args) as store:
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
    calibration = None
    if args.calibration:
        from rig.population.calfile import load_calibration

        calibration = load_calibration(args.calibration)  # a bad file: one line naming it
    study = run_study(bats, sources, notes, calibration, args.calibration or "")
    if args.plot_dir:
        from rig.report.population_plots import plot_population

        for path in plot_population(study, args.plot_dir):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        json.dump(study.as_dict(), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    console = out()
    tag = " (SYNTHETIC sample data)" if study.synthetic else ""
    table = new_table(title=f"Fig. 6: 50 Hz bins averaged over ±25 Hz, {len(study.bats)} bats{tag}")
    for col in ("hoop Hz", "n", *(heading(m) for m in METRICS)):
        table.add_column(col, justify="right")
    by_centre: dict[float, dict[str, Any]] = {}
    for name, bins in study.bins.items():
        for b in bins:
            by_centre.setdefault(b.center_hz, {"n": b.n})[name] = b.mean
    for centre in sorted(by_centre):
        row = by_centre[centre]
        cells = [f"{row[m]:.4g}" if m in row else "" for m in METRICS]
        table.add_row(f"{centre:.0f}", str(row["n"]), *cells)
    console.print(table)
    for material, d in study.materials().items():
        console.print(f"{material}: {d['n']} bats, hoop {d['hoop_min_hz']:.0f}-{d['hoop_max_hz']:.0f} Hz")
    for name, t in study.trend.items():
        if t.get("slope_per_khz") is not None:
            calibrated = t.get("calibrated_slope_per_khz")
            console.print(
                f"{name}: {t['slope_per_khz']:+.4g} per 1000 Hz"
                f" (model {t.get('model_slope_per_khz', 0.0):+.4g}"
                + ("" if calibrated is None else f", calibrated {calibrated:+.4g}")
                + f"), r = {t['r']:.3f}"
            )
    cal = study.calibrated
    if cal is not None:
        metric = cal["metric"]
        points = ", ".join(
            f"{h:.0f} Hz {v:.4f}" for h, v in zip(cal["hoop_hz"], cal[metric], strict=True) if h % 500 == 0
        )
        console.print(
            f"calibrated model ({cal['variant']}, {args.calibration}, LOO RMSE {cal['loo_rmse']:.4f}):"
            f" {metric} {points}"
        )
    for note in study.notes:
        console.print(f"note: {note}")
    return 0


def add_parsers(sub: Any) -> None:
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
    p.add_argument("--db", metavar="FILE", help=f"{DB_HELP}; for --bat")
    p.add_argument(
        "--window", type=float, metavar="S", help="analysis window per hit, s (default: automatic)"
    )
    p.add_argument(
        "--max-resolution", type=float, metavar="HZ", help="refuse windows coarser than this (20 Hz)"
    )
    p.add_argument("--min-coherence", type=float, metavar="X", help="least coherence at the hoop mode (0.9)")
    p.add_argument(
        "--band-min",
        type=float,
        metavar="HZ",
        help="lowest frequency searched for modes (3/T, at least 10 Hz)",
    )
    p.add_argument(
        "--band-max",
        type=float,
        metavar="HZ",
        help="highest frequency searched (where the hammer's spectrum drops)",
    )
    p.set_defaults(handler=cmd_modal_analyze)

    p = msub.add_parser(
        "simulate", help="write a simulated impact test", description=cmd_modal_simulate.__doc__
    )
    p.add_argument("out", metavar="OUT", help="output file: .csv, or .uff/.unv")
    p.add_argument(
        "--hoop", type=float, nargs="+", metavar="HZ", help="hoop frequencies (default 1800 and 1.7x)"
    )
    p.add_argument("--bending", type=float, default=175.0, metavar="HZ", help="first bending frequency")
    p.add_argument("--hits", type=positive_int, default=5, help="number of hits")
    p.add_argument("--interval", type=float, default=0.5, metavar="S", help="time between hits, s")
    p.add_argument("--noise", type=float, default=1e-3, help="noise std as a fraction of each channel's peak")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--double-hit", type=positive_int, metavar="N", help="make hit N a double hit (a fault)")
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
    p.add_argument(
        "--certify",
        type=positive_int,
        metavar="N",
        help="first certify N simulated bats (hoop 1400-3000 Hz) into --db on the simulated rig",
    )
    p.add_argument("--scene", default="lab", help="simulated rig for --certify (default lab)")
    p.add_argument("--seed", type=int, default=0, help="population seed for --certify (default 0)")
    p.add_argument("--altered", type=int, default=0, metavar="K", help="of the N bats, K altered (ALT- ids)")
    p.add_argument(
        "--alteration", type=float, default=0.025, metavar="BBCOR", help="altered bats' extra BBCOR (0.025)"
    )
    p.add_argument("--procedure", default="bbcor", help="procedure for --certify (default bbcor)")
    p.add_argument("--calibration", metavar="CAL.json", help="overlay this calibrated model on Fig. 6")
    p.set_defaults(handler=cmd_study)
