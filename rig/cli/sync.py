"""`rig sync`: push a rig's records (its SQLite file, or any store) to the lab's store."""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from typing import Any


def cmd_sync(args: argparse.Namespace) -> int:
    """rig sync: copy the runs of --from missing in --to (or their new entries), verbatim.

    Idempotent (a second sync adds nothing); the source is verified before and the target after;
    a run whose history differs between the two is refused and nothing is written; neither side
    is ever rewritten. Both stores must use chain format 2 (every store made since lab records).
    """
    from rig.store import Store
    from rig.store._sync import sync

    if str(args.source) == str(args.target):
        from rig.core.errors import ConfigError

        raise ConfigError("--from and --to name the same store", source="command line")
    with Store.open(args.source, create=False) as source, Store.open(args.target, create=True) as target:
        report = sync(source, target)
    if args.json:
        json.dump(asdict(report), sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        print(report)
    return 0


def add_parsers(sub: Any) -> None:
    """`rig sync`."""
    p = sub.add_parser("sync", help="push a rig's records to the lab's store", description=cmd_sync.__doc__)
    p.add_argument(
        "--from", dest="source", required=True, metavar="STORE", help="the rig's store (file or URL)"
    )
    p.add_argument(
        "--to", dest="target", required=True, metavar="STORE", help="the lab's store (file or URL)"
    )
    p.add_argument("--json", action="store_true", help="the report as JSON")
    p.set_defaults(handler=cmd_sync)
