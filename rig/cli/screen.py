"""`rig screen`: a field screen from a bat's hoop frequency (given, or from taps), never a verdict."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import Bounds, check_flags
from rig.cli.common import console as out
from rig.core.errors import ConfigError

BOUNDS: Bounds = {
    "hoop_hz": ("--hoop-hz", 200.0, 10000.0, "Hz"),
    "certified_hoop_hz": ("--certified-hoop-hz", 200.0, 10000.0, "Hz"),
    "coverage": ("--coverage", 0.5, 0.999, ""),
}
CANNOT = (
    "what a screen cannot say: whether the bat meets its standard (only a test on the rig does);"
    " sources find hoop frequency strongly correlated with performance but publish no prediction error"
)


def _needed(args: argparse.Namespace) -> None:
    """One line naming the first missing or conflicting flag (argparse's own would print two)."""
    where = "command line"
    if (args.hoop_hz is None) == (args.recording is None):
        raise ConfigError(
            "give the hoop frequency: --hoop-hz F or --recording REC.wav (one of them)", source=where
        )
    for flag, value in (("--calibration CAL.json", args.calibration), ("--model-id ID", args.model_id)):
        if not value:
            raise ConfigError(
                f"{flag} is needed: the calibration and the bat model to screen against", source=where
            )


def _limit(args: argparse.Namespace, metric: str) -> tuple[float, str]:
    if args.limit is not None:
        from rig.measure.registry import metric as registered

        low, high = registered(metric).limit_range
        if not low < args.limit <= high:
            raise ConfigError(
                f"--limit {args.limit:g} is outside ({low:g}, {high:g}] for {metric}", source="command line"
            )
        return float(args.limit), "given (--limit)"
    from rig.protocols.procedure import Procedure

    proc = Procedure.load(metric)
    return proc.limit, f"built-in procedure {metric}: {proc.edition}"


def cmd_screen(args: argparse.Namespace) -> int:
    """rig screen: the calibrated prediction at a bat's hoop frequency, its interval, the limit, the fall."""
    _needed(args)
    check_flags(args, BOUNDS)
    from rig.population.calfile import load_calibration
    from rig.population.screen import bat_model, screen

    cal = load_calibration(args.calibration)
    model = bat_model(cal, args.model_id, source=args.calibration)
    limit, limit_source = _limit(args, cal.metric)
    u_hoop, taps = 0.0, None
    if args.recording is not None:
        from rig.modal.tap import analyze_tap
        from rig.modal.wav import read_wav

        taps = analyze_tap(read_wav(args.recording))
        hoop, u_hoop, source = taps.hoop.frequency_hz, taps.hoop.u_hz, f"tap recording {args.recording}"
    else:
        hoop, source = float(args.hoop_hz), "given (--hoop-hz)"
    result = screen(
        cal,
        model,
        hoop,
        limit,
        u_hoop_hz=u_hoop,
        hoop_source=source,
        model_hoop_hz=args.certified_hoop_hz,
        limit_source=limit_source,
        coverage=args.coverage,
    )
    if args.json:
        payload = result.as_dict()
        if taps is not None:
            payload["tap"] = taps.as_dict()
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    _print(result, taps)
    return 0


def _print(r: Any, taps: Any) -> None:
    console = out()
    name = r.metric.upper() if r.metric != "bbs" else "BBS (m/s)"
    console.print(f"SCREEN of bat model {r.model_id} ({r.metric}): a screen, not a certification; no verdict")
    if taps is not None:
        console.print(
            f"hoop frequency: {r.hoop_hz:.1f} ± {2 * r.u_hoop_hz:.2g} Hz (k=2) from {r.hoop_source}"
            f" ({len(taps.tap_times_s)} taps)"
        )
    else:
        console.print(f"hoop frequency: {r.hoop_hz:.1f} Hz, {r.hoop_source}")
    word = "fallen" if r.fall_hz >= 0 else "risen"
    console.print(
        f"the model's hoop frequency in the lab: {r.model_hoop_hz:.1f} Hz ({r.model_hoop_source});"
        f" {word} by {abs(r.fall_hz):.1f} Hz ({abs(r.fall_percent):.2f} %)"
    )
    console.print(
        f"predicted {name}: {r.predicted:.4f}, {100 * r.coverage:g} % prediction interval"
        f" {r.interval[0]:.4f} - {r.interval[1]:.4f} (t = {r.t_factor:.3f}, {r.dof} degrees of freedom)"
    )
    where = {"above": "lies above it", "below": "lies at or below it", "across": "straddles it"}
    exceeds = "exceeds" if r.predicted_exceeds_limit else "does not exceed"
    console.print(
        f"limit {r.limit:g} ({r.limit_source}): the prediction {exceeds} it;"
        f" the interval {where[r.interval_vs_limit]}"
    )
    for note in (*r.notes, *(taps.warnings if taps is not None else ())):
        console.print(f"note: {note}")
    console.print(CANNOT)


def add_parsers(sub: Any) -> None:
    """`rig screen`."""
    p = sub.add_parser(
        "screen",
        help="a field screen from a bat's hoop frequency: the calibrated prediction, never a verdict",
        description=(
            "The calibrated model's prediction at the bat's hoop frequency (given, or found in a tap"
            " recording by `rig modal tap`), its prediction interval, whether it exceeds the limit, and"
            " how far the hoop frequency has fallen from the model's. A screen, not a certification"
            " (docs/screening.md)."
        ),
    )
    p.add_argument("--hoop-hz", type=float, metavar="F", help="the bat's hoop frequency, Hz (200-10000)")
    p.add_argument("--recording", metavar="REC.wav", help="a one-channel WAV of taps on the barrel")
    p.add_argument("--calibration", metavar="CAL.json", help="from `rig model calibrate`")
    p.add_argument(
        "--model-id", metavar="ID", help="the bat model: its sample's bat_id in the calibration's population"
    )
    p.add_argument(
        "--certified-hoop-hz",
        type=float,
        metavar="F0",
        help="the model's hoop frequency as tested in the lab (default: the calibration's, for that bat)",
    )
    p.add_argument("--limit", type=float, help="the limit (default: the built-in procedure's for the metric)")
    p.add_argument("--coverage", type=float, default=0.95, help="the interval's coverage (default 0.95)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(handler=cmd_screen)
