"""`rig-study population`: the population study, hoop frequency against bending and performance."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from rig.cli.common import ConfigError, new_table, open_db, output_dir, positive_int
from rig.cli.common import console as out


def cmd_study(args: argparse.Namespace) -> int:
    """rig-study population: hoop frequency against bending and performance (paper section 5)."""
    from rig.measure.registry import heading
    from rig.population import METRICS, load_population
    from studies.cli.certify import check_args
    from studies.population.study import run_study

    check_args(args)
    output_dir(args.plot_dir, "--plot-dir")
    if args.certify is not None:
        from studies.cli.certify import run as certify_population

        code = certify_population(args)
        if code or not (args.json or args.plot_dir or args.calibration):
            return code
    bats, sources, notes = [], [], []
    data = args.data
    if not data and not args.db:
        import rig.protocols

        data = [str(Path(rig.protocols.__file__).parent / "examples" / "population.csv")]
        print("rig-study: no --data or --db: using the SYNTHETIC sample population", file=sys.stderr)
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
        raise ConfigError(
            f"bat id(s) in more than one source: {', '.join(twice)}", source="rig-study population"
        )
    if not bats:
        raise ConfigError("no bats with a hoop frequency in the given sources", source="rig-study population")
    calibration = None
    if args.calibration:
        from rig.population.calfile import load_calibration

        calibration = load_calibration(args.calibration)  # a bad file: one line naming it
    study = run_study(bats, sources, notes, calibration, args.calibration or "")
    if args.plot_dir:
        from studies.population.plots import plot_population

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


def add_parser(sub: Any) -> None:
    """`rig-study population`."""
    p = sub.add_parser(
        "population", help="population study: hoop frequency vs performance", description=cmd_study.__doc__
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
