"""`rig modal analyze|simulate`: hoop and bending frequencies from impact tests."""

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


def _modes_table(title: str, extra: tuple[str, ...], rows: list[tuple[Any, ...]]) -> Any:
    """Print a table of modes (kind, f, U, damping and `extra` columns); return the console."""
    table = new_table(title=title)
    for col in ("kind", "f (Hz)", "U (Hz, k=2)", "damping", *extra):
        table.add_column(col, justify="left" if col == "kind" else "right")
    for m, *cells in rows:
        u = f"{m.expanded_uncertainty_hz:.2g}"
        table.add_row(m.kind, f"{m.frequency_hz:.1f}", u, f"{m.damping_ratio:.4f}", *cells)
    console = out()
    console.print(table)
    return console


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
    console = _modes_table(
        f"Modes of {args.file} ({result.n_hits} hits, resolution {result.resolution_hz:.3g} Hz)",
        ("|H1|/|H2|", "coherence"),
        [(m, f"{m.magnitude_ratio:.3g}", f"{m.coherence:.3f}") for m in result.modes],
    )
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


def cmd_modal_tap(args: argparse.Namespace) -> int:
    """rig modal tap: the hoop frequency from a one-channel WAV of taps on the barrel (no force signal)."""
    from rig.modal.tap import analyze_tap
    from rig.modal.wav import read_wav

    output_file(args.plot, "--plot")
    result = analyze_tap(read_wav(args.file))
    payload = result.as_dict()
    if args.plot:
        from rig.report.modal_plots import plot_tap

        for path in plot_tap(result, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    console = _modes_table(
        f"Modes of {args.file} ({payload['n_taps']} taps, {result.window_s:.3g} s each)",
        ("amplitude",),
        [(m, f"{m.amplitude:.2f}") for m in result.modes],
    )
    hoop = result.hoop
    console.print(
        f"first hoop frequency: {hoop.frequency_hz:.1f} ± {hoop.expanded_uncertainty_hz:.2g} Hz (k=2)"
    )
    for w in result.warnings:
        console.print(f"note: {w}")
    return 0


def add_parsers(sub: Any) -> None:
    """`rig modal analyze|simulate`."""
    modal = sub.add_parser("modal", help="modal analysis of impact tests (hoop frequency)")
    msub = modal.add_subparsers(dest="modal_command", required=True, metavar="MODAL_COMMAND")
    p = msub.add_parser(
        "analyze", help="hoop and bending modes of a recording", description=cmd_modal_analyze.__doc__
    )
    p.add_argument(
        "file",
        metavar="FILE",
        help="recording: .csv (time_s,force_N,accel1_ms2,accel2_ms2), .uff, or .wav (force, response)",
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
        "tap", help="hoop frequency from a WAV of taps on the barrel", description=cmd_modal_tap.__doc__
    )
    p.add_argument("file", metavar="REC.wav", help="one-channel WAV: three or more taps, 50 ms or more apart")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--plot", metavar="FILE", help="plot the taps' spectrum with the modes (PNG and SVG)")
    p.set_defaults(handler=cmd_modal_tap)

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
