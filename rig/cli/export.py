"""`rig export`: an analysts' view of the records (shots, runs_summary) as CSV or Parquet."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from rig.cli.common import open_db, resolve_run
from rig.core.dbpath import DB_HELP


def cmd_export(args: argparse.Namespace) -> int:
    """rig export: write the `shots` or `runs_summary` view (of one run or all) as CSV or Parquet."""
    from rig.report.export import check_request, export

    check_request(args.view, args.format, args.output)  # before the store is opened
    with open_db(args, readonly=True) as store:
        run_id = resolve_run(store, args.run) if args.run else None
        n = export(store, args.view, args.format, args.output, run_id, stdout=sys.stdout)
    if args.output != "-":
        print(f"wrote {n} rows of {args.view} to {args.output}", file=sys.stderr)
    return 0


def add_parsers(sub: Any) -> None:
    """`rig export`."""
    p = sub.add_parser(
        "export", help="write an analysts' view as CSV or Parquet", description=cmd_export.__doc__
    )
    p.add_argument("--db", metavar="FILE", help=DB_HELP)
    # checked by the command, not by argparse, so that a wrong name is one line naming the choices
    p.add_argument("--view", required=True, metavar="VIEW", help="shots or runs_summary")
    p.add_argument("--run", metavar="RUN", help="only this run (a unique prefix will do, or 'last')")
    p.add_argument("--format", default="csv", metavar="FORMAT", help="csv (default) or parquet")
    p.add_argument(
        "--output", "-o", required=True, metavar="FILE", help="the file to write; '-': CSV to stdout"
    )
    p.set_defaults(handler=cmd_export)
