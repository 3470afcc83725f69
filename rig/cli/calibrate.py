"""`rig model calibrate`: fit the barrel's m2 and c2 (and what else the data need) to measured bats."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rig.core.errors import ConfigError


def cmd_calibrate(args: argparse.Namespace) -> int:
    """rig model calibrate: the fit, its covariance, scatter and leave-one-out error; writes CAL.json."""
    from rig.population import load_population
    from rig.population.calfile import calibration_record, write_calibration
    from rig.population.calibrate import calibrate

    data, output = Path(args.data), Path(args.output)
    if output.exists() and data.exists() and output.resolve() == data.resolve():
        raise ConfigError("--output would overwrite the data file", source=str(output))
    bats = load_population(data)
    cal = calibrate(bats, metric=args.metric)
    record = calibration_record(cal, data.read_bytes(), str(data))
    write_calibration(record, output)
    if args.json:
        json.dump(record, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        _print(record)
    print(f"wrote {output}", file=sys.stderr)
    return 0


def _print(record: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    prov = record["provenance"]
    console.print(
        f"Calibration on {prov['n_bats']} bats ({record['metric']}), hoop {prov['hoop_min_hz']:.0f}-"
        f"{prov['hoop_max_hz']:.0f} Hz, data sha256 {prov['data_sha256'][:12]}..."
    )
    table = Table(title="Variants (chosen by leave-one-out prediction error)")
    for col in ("variant", "parameters (+- 1 sigma)", "scatter", "LOO RMSE", ""):
        table.add_column(col)
    for v in record["variants"]:
        params = ", ".join(
            f"{k} = {val:.4g}" + ("" if v["uncertainty"][k] is None else f" +- {v['uncertainty'][k]:.2g}")
            for k, val in v["parameters"].items()
        )
        loo = "not identified" if v["loo_rmse"] is None else f"{v['loo_rmse']:.4f}"
        mark = "chosen" if v["variant"] == record["variant"] else ""
        table.add_row(v["variant"], params, f"{v['scatter']:.4f}", loo, mark)
    console.print(table)
    names = list(record["parameters"])
    cov = Table(title=f"Covariance of {record['variant']} ({', '.join(record['units'][n] for n in names)})")
    cov.add_column("")
    for n in names:
        cov.add_column(n, justify="right")
    for n, row in zip(names, record["covariance"], strict=True):
        cov.add_row(n, *(f"{x:.3g}" for x in row))
    console.print(cov)
    for note in record["notes"]:
        console.print(f"note: {note}")
    console.print(
        f"chosen: {record['variant']}; bat-to-bat scatter after the fit {record['scatter']:.4f},"
        f" leave-one-out prediction RMSE {record['loo_rmse']:.4f}"
        f" (impact {record['default_location_in']:g} in from the barrel end where a row gives no location_in)"
    )


def add_parser(msub: Any) -> None:
    """`rig model calibrate` under the `rig model` subcommands."""
    from rig.population.calibrate import DEFAULT_LOCATION_IN, MIN_BATS, MIN_HOOP_SPAN_HZ

    p = msub.add_parser(
        "calibrate",
        help="fit the barrel's m2, c2 (and a k1 scale or an offset) to measured bats",
        description=(
            "Fit the model constants the paper's ball tests leave open (barrel hoop mass m2, damping c2,"
            " and as variants a contact-stiffness scale or an offset) to a population of measured bats;"
            " choose the variant by leave-one-out prediction error. Needs hoop_hz, moi_kgm2, length_in"
            f" and the metric for at least {MIN_BATS} bats spanning {MIN_HOOP_SPAN_HZ:.0f} Hz; location_in"
            f" defaults to {DEFAULT_LOCATION_IN:g} in from the barrel end."
        ),
    )
    p.add_argument("--data", required=True, metavar="POPULATION", help="population file (.csv or .toml)")
    p.add_argument("--metric", choices=("bbcor", "besr", "bbs"), default="bbcor", help="metric to fit")
    p.add_argument("--output", required=True, metavar="CAL.json", help="where to write the calibration")
    p.add_argument("--json", action="store_true", help="print the calibration record as JSON")
    p.set_defaults(handler=cmd_calibrate)
