"""`rig compare`: two labs' or rigs' results bat by bat, or one store's retests, by E_n and z."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from rig.cli.common import add_columns, add_plain_row, console, default_db, new_table
from rig.core.dbpath import DB_HELP


def cmd_compare(args: argparse.Namespace) -> int:
    """rig compare: score bats tested in two stores (or two runs_summary exports) by E_n and z
    (ISO 13528), the first --db as x and the second as the reference X; with one --db, each retest
    of a bat (same bat id and procedure) against its earlier result by E_n.

    Pairs are by bat id and procedure, the newest finished result of each side. E_n uses both
    results' expanded U (|E_n| <= 1 satisfactory); z = (x - X) / sigma_pt with --sigma-pt, else
    sigma_pt is Algorithm A's robust SD of the differences (at least 8 bats). Exit 0 once scored
    (whatever the scores), 2 on an error.
    """
    from rig.core.errors import ConfigError
    from rig.quality.compare import compare, paired, retests
    from rig.report.compare_sources import load, shown_source

    sources = args.db or [str(default_db())]
    if len(sources) > 2:
        raise ConfigError(
            f"give one --db (its retests) or two (A against B), not {len(sources)}", source="--db"
        )
    loaded = [load(source) for source in sources]
    if len(loaded) == 2:
        mode, pairs = "two sources", paired(loaded[0], loaded[1])
        result = compare(pairs, args.sigma_pt)
    else:
        mode, pairs = "retests", retests(loaded[0])
        result = compare(pairs, args.sigma_pt, z=False)
    names = [shown_source(s) for s in sources]
    payload = _payload(mode, names, result)
    if args.json:
        json.dump(payload, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
        return 0
    _table(payload)
    return 0


def _payload(mode: str, names: list[str], result: Any) -> dict[str, Any]:
    """The comparison as JSON: its sources, sigma_pt, and per bat x, U_x, X, U_X, E_n, z."""
    sigma = result.sigma
    robust = sigma.robust
    return {
        "mode": mode,
        "sources": names,
        "sigma_pt": {
            "value": sigma.value,
            "source": sigma.source,
            "robust_mean_difference": None if robust is None else robust.mean,
            "bats": None if robust is None else robust.p,
        },
        "pairs": [
            {
                "bat_id": row.pair.x.bat_id,
                "procedure": row.pair.x.procedure,
                "x": row.pair.x.to_json(),
                "X": row.pair.ref.to_json(),
                "difference": row.score.difference,
                "E_n": row.score.en,
                "E_n_assessment": row.score.en_assessment,
                "z": row.score.z,
                "z_assessment": row.score.z_assessment,
            }
            for row in result.rows
        ],
        "notes": list(result.notes),
    }


def _table(payload: dict[str, Any]) -> None:
    out = console()
    if payload["mode"] == "retests":
        title = f"Retests in {payload['sources'][0]}: each result (x) against the bat's earlier one (X)"
    else:
        title = f"{payload['sources'][0]} (x) against {payload['sources'][1]} (X)"
    table = new_table(title=title)
    add_columns(table, "bat", "procedure", "run x", "run X")
    add_columns(table, "x", "U_x", "X", "U_X", "x - X", "E_n", justify="right")
    add_columns(table, "E_n says")
    add_columns(table, "z", justify="right")
    add_columns(table, "z says")
    for p in payload["pairs"]:
        x, ref = p["x"], p["X"]
        add_plain_row(
            table,
            p["bat_id"],
            p["procedure"],
            x["run_id"][:12],
            ref["run_id"][:12],
            f"{x['mean']:.6g}",
            f"{x['U']:.2g}",
            f"{ref['mean']:.6g}",
            f"{ref['U']:.2g}",
            f"{p['difference']:+.3g}",
            f"{p['E_n']:+.2f}",
            p["E_n_assessment"],
            "-" if p["z"] is None else f"{p['z']:+.2f}",
            p["z_assessment"] or "-",
        )
    if not payload["pairs"]:
        what = "no bat was retested" if payload["mode"] == "retests" else "no bat was tested in both"
        out.print(
            f"{what} (same bat id and procedure, a finished run with a result on each side)",
            markup=False,
            highlight=False,
        )
        return
    out.print(table)
    sigma = payload["sigma_pt"]
    if sigma["value"] is not None:
        how = (
            "given"
            if sigma["source"] == "given"
            else (
                f"Algorithm A's robust SD of {sigma['bats']} differences (robust mean difference "
                f"{sigma['robust_mean_difference']:+.3g})"
            )
        )
        out.print(f"sigma_pt = {sigma['value']:.3g} ({how})", markup=False, highlight=False)
    for note in payload["notes"]:
        out.print(note, markup=False, highlight=False)


def add_parsers(sub: Any) -> None:
    """`rig compare`."""
    p = sub.add_parser(
        "compare",
        help="score two labs' results (or one store's retests) by E_n and z",
        description=cmd_compare.__doc__,
    )
    p.add_argument(
        "--db",
        action="append",
        metavar="STORE",
        help="a record store (file or postgresql:// URL) or a runs_summary export (CSV or Parquet); "
        "twice: the first is scored against the second. " + DB_HELP,
    )
    p.add_argument("--sigma-pt", type=float, metavar="S", help="sigma_pt for z, in the metric's unit")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(handler=cmd_compare)
