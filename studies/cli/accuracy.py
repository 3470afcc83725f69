"""`rig-study accuracy`: the work-precision study of the collision solvers."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import Bounds, check_flags, new_table, output_file, positive_int
from rig.cli.common import console as out

BOUNDS: Bounds = {"repeats": ("repeats", 1, 100, "")}


def cmd_accuracy(args: argparse.Namespace) -> int:
    """rig-study accuracy: the work-precision study of the collision solvers."""
    from studies.accuracy.precision import work_precision
    from studies.accuracy.stopwatch import stamped, stopwatch

    check_flags(args, BOUNDS)
    output_file(args.plot, "--plot")
    from rig.progress import steps

    with steps(None, "work-precision: solves timed") as bar:
        timer = bar.counted(stopwatch(quick=args.quick, repeats=args.repeats))
        study = stamped(lambda: work_precision(quick=args.quick, timer=timer))
    if args.plot:
        from studies.accuracy.plots import plot_work_precision

        for path in plot_work_precision(study, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        json.dump([row.as_dict() for row in study.rows], sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        from studies.accuracy.plots import precision_table

        table = precision_table(study)
        if not out().is_terminal:
            table.box = new_table().box
        out().print(table)
    return 0


def add_parser(sub: Any) -> None:
    """`rig-study accuracy`."""
    p = sub.add_parser("accuracy", help="work-precision study: error against cost of each solver")
    p.add_argument("--plot", metavar="FILE", help="write the plots (PNG and SVG)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    p.add_argument("--quick", action="store_true", help="fewer tolerances and methods (a smoke run)")
    p.add_argument("--repeats", type=positive_int, default=5, help="timed repeats (best of N, 1-100)")
    p.set_defaults(handler=cmd_accuracy)
