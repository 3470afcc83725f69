"""`rig model crosscheck`: each bat's measured metric against the calibrated model's prediction interval."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import console as out
from rig.cli.common import new_table
from rig.core.errors import ConfigError


def interval_rule(t: float, dof: int, coverage: float) -> str:
    """How the interval is made, in one sentence."""
    return (
        f"interval: predicted +- t sqrt(u_model^2 + u_scatter^2 + u_measured^2), t = {t:.3f}"
        f" (Student-t, {dof} degrees of freedom), coverage {100 * coverage:g} %"
    )


def cmd_crosscheck(args: argparse.Namespace) -> int:
    """rig model crosscheck: prediction, interval, measured, z and flagged for each bat."""
    from rig.population import load_population
    from rig.population.calfile import load_calibration
    from rig.population.crosscheck import check_population_metric, crosscheck_bats, dof, t_factor

    cal = load_calibration(args.calibration)
    if args.ball:
        from rig.cli.fit_ball import check_calibration_ball

        check_calibration_ball(cal, args.ball, "rig model crosscheck")
    t = t_factor(cal, args.coverage)
    bats = load_population(args.data)
    if not bats:
        raise ConfigError("no bats in the file", source=args.data)
    check_population_metric(cal)
    if all(b.metric(cal.metric) is None for b in bats):
        raise ConfigError(
            f"no {cal.metric} values: the calibration is for {cal.metric} and the column is absent or empty",
            source=args.data,
        )
    checks = crosscheck_bats(cal, bats, coverage=args.coverage)
    outside = sum(c.extrapolated for c in checks)
    if outside:  # on stderr, so that --json readers see it too
        print(
            f"warning: {outside} of {len(checks)} bats lie outside the calibrated range"
            f" ({cal.provenance.range_text()}): predicted by extrapolation, so a flag there may mean"
            " another population rather than an altered bat",
            file=sys.stderr,
        )
    if args.json:
        json.dump([c.as_dict() for c in checks], sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    _print(checks, cal, interval_rule(t, dof(cal), args.coverage))
    return 0


def _print(checks: list[Any], cal: Any, rule: str) -> None:
    prov = cal.provenance
    table = new_table(
        title=f"Cross-check of {cal.metric} against the calibration of {prov.n_bats} bats"
        f" ({prov.range_text()}, data sha256 {prov.data_sha256[:12]}...)"
    )
    for col in ("bat", "hoop Hz", "predicted", "interval", "measured", "z", "flagged"):
        table.add_column(col, justify="left" if col == "bat" else "right")
    for c in checks:
        flag = "-" if c.flagged is None else ("FLAGGED" if c.flagged else "consistent")
        if c.extrapolated:
            flag += " (extrapolated)"
        table.add_row(
            c.bat_id,
            f"{c.hoop_hz:.0f}",
            f"{c.predicted:.4f}",
            f"{c.interval[0]:.4f} - {c.interval[1]:.4f}",
            "-" if c.measured is None else f"{c.measured:.4f}",
            "-" if c.z is None else f"{c.z:+.2f}",
            flag,
        )
    console = out()
    console.print(table)
    console.print(rule)
    unknown = sum(not c.u_measured_known for c in checks)
    if unknown:
        console.print(
            f"note: {unknown} of {len(checks)} bats give no u_{cal.metric}: their own measurement"
            " uncertainty is taken as 0 (the interval is then narrower than it should be)"
        )
    ball = cal.ball or {}
    sha = str(ball.get("sha256"))[:12]
    which = f"{ball.get('file')} (lot {ball.get('lot') or '-'}, sha256 {sha}...)" if ball else "the paper's"
    console.print(f"ball: {which}")
    flagged = sum(bool(c.flagged) for c in checks)
    console.print(f"{flagged} of {len(checks)} bats flagged")


def _coverage(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def add_parser(msub: Any) -> None:
    """`rig model crosscheck` under the `rig model` subcommands."""
    p = msub.add_parser(
        "crosscheck",
        help="each bat's measured metric against the calibrated model's prediction interval",
        description=(
            "For each bat: the calibrated model's prediction at its hoop frequency, MOI, length and"
            " impact location; the prediction interval (parameter covariance, bat-to-bat scatter and the"
            " bat's own u_<metric> column, Student-t with the calibration's n - p degrees of freedom); the"
            " measured value, z and whether it is flagged (outside the interval)."
        ),
    )
    p.add_argument("--data", required=True, metavar="BATS", help="population file (.csv or .toml)")
    p.add_argument("--calibration", required=True, metavar="CAL.json", help="from `rig model calibrate`")
    p.add_argument("--coverage", type=_coverage, default=0.95, help="the interval's coverage (default 0.95)")
    p.add_argument(
        "--ball",
        metavar="BALL.json",
        help="the ball the bats were tested with: refused unless it is the calibration's ball",
    )
    p.add_argument("--json", action="store_true", help="print a JSON list, one object per bat")
    p.set_defaults(handler=cmd_crosscheck)
