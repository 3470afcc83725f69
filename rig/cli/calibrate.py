"""`rig model calibrate`: fit the barrel's m2 and c2 (and what else the data need) to measured bats."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rig.cli.common import console as out
from rig.cli.common import new_table, output_file
from rig.core.errors import ConfigError
from rig.measure.registry import cross_checked

if TYPE_CHECKING:
    from rig.population.budget import Budget


def gather(
    data: str | None,
    db: str | None,
    who: str,
    standard: str | None = None,
    conditions: list[Any] | None = None,
) -> tuple[list[Any], bytes, str, list[str]]:
    """The bats of a population file and/or a record store's certified runs (ids unique across both).

    Returns the bats, the bytes the provenance hashes (the file's bytes, then the store's rows as
    canonical JSON), a name for the sources, and notes on store bats left out. `standard`: only the
    store's runs of that metric, their speeds and ball masses appended to `conditions`.
    """
    from rig.population.dataset import read_population

    if not data and not db:
        raise ConfigError("give --data POPULATION, --db STORE or both", source=who)
    bats: list[Any] = []
    names: list[str] = []
    notes: list[str] = []
    blob = b""
    if data:
        read, raw = read_population(data)  # the bytes read, not the file again: it may change
        bats += read
        blob += raw
        names.append(str(data))
    if db:
        from rig.population.store_source import bats_from_store
        from rig.store import Store

        with Store.open(db, create=False) as store:
            stored, notes = bats_from_store(store, standard, conditions)
        bats += stored
        rows = [b.model_dump(mode="json") for b in stored]
        blob += json.dumps(rows, sort_keys=True, separators=(",", ":")).encode()
        names.append(f"store {db}")
    ids = [b.bat_id for b in bats]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ConfigError(f"bat id(s) in more than one source: {', '.join(twice)}", source=who)
    return bats, blob, " + ".join(names), notes


def cmd_calibrate(args: argparse.Namespace) -> int:
    """rig model calibrate: the fit, its covariance, scatter and leave-one-out error; writes CAL.json.

    Ctrl-C (SIGINT) ends it with one line saying what it was doing and whether the file was
    written (whole or not at all: a temporary file beside it, then a rename), exit 130.
    """
    from rig.population.budget import Budget

    output = output_file(args.output, "--output")
    assert output is not None  # a required flag
    show = sys.stderr.isatty() if args.progress is None else args.progress

    def progress(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    budget = Budget(max_seconds=args.max_seconds, progress=progress if show else None)
    budget.doing = "reading the bats"  # the time limit counts from the command's start
    existed = output.exists()
    try:
        return _calibrate(args, output, budget)
    except KeyboardInterrupt:
        if budget.doing == WRITTEN:
            told = f"{output} was written"
        else:
            told = f"no calibration written ({output} {'left as it was' if existed else 'not created'})"
        at = f"{budget.doing}, {budget.elapsed():.1f} s in"
        print(f"rig model calibrate: interrupted ({at}); {told}", file=sys.stderr)
        return 130


WRITTEN = "printing the calibration"  # the stage after the file is in place


def _calibrate(args: argparse.Namespace, output: Path, budget: Budget) -> int:
    """cmd_calibrate's work, `budget.doing` saying what it is doing."""
    from rig.population.calfile import calibration_record, write_calibration
    from rig.population.calibrate import PAPER_BASE, calibrate, fitted_quantity
    from rig.report.export import atomic_write

    for source in (args.data, args.db):
        if (
            source
            and output.exists()
            and Path(source).exists()
            and output.resolve() == Path(source).resolve()
        ):
            raise ConfigError("--output would overwrite a data source", source=str(output))
    fitted = fitted_quantity(args.metric)
    standard = None if fitted == args.metric else args.metric  # read only the runs of its standard
    conditions: list[Any] = []
    bats, blob, names, store_notes = gather(args.data, args.db, "rig model calibrate", standard, conditions)
    for note in store_notes:
        print(f"rig: {note}", file=sys.stderr)
    ball = None
    kwargs: dict[str, Any] = {}
    if standard is None and args.ball_mass_kg is not None:
        raise ConfigError(
            f"--ball-mass-kg is for a BPF or USA Softball BBS calibration; {args.metric} fits the"
            " lab's baseball",
            source="rig model calibrate",
        )
    if standard is not None:
        speed, mass = _standard_conditions(args, conditions)
        kwargs["speed_m_s"] = speed
        kwargs["base"] = PAPER_BASE.model_copy(update={"m1": mass})
    if args.ball:
        from rig.cli.fit_ball import load_ball
        from rig.physics.ball_law import ball_record

        law, sha = load_ball(args.ball)
        ball = ball_record(law, sha, args.ball)
        kwargs["base"] = law.apply(PAPER_BASE)
    cal = calibrate(bats, metric=args.metric, budget=budget, **kwargs)
    budget.doing = "writing the calibration"
    record = calibration_record(cal, blob, names, ball=ball)

    def write(tmp: Path) -> None:
        write_calibration(record, tmp)

    atomic_write(output, write)
    budget.doing = WRITTEN
    if args.json:
        json.dump(record, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        _print(record)
    print(f"wrote {output}", file=sys.stderr)
    return 0


def _standard_conditions(args: argparse.Namespace, found: list[Any]) -> tuple[float, float]:
    """The inbound speed (m/s) and ball mass (kg) a calibration of a BPF or a USA Softball BBS solves
    at: the store runs' own (all alike), else the standard's speed and --ball-mass-kg."""
    from rig.measure.registry import metric

    who = "rig model calibrate"
    speeds = sorted({c.speed_m_s for c in found})
    masses = sorted({c.ball_mass_kg for c in found})
    if len(speeds) > 1 or len(masses) > 1:
        raise ConfigError(
            f"the store's {args.metric} runs fired at {', '.join(f'{v:g}' for v in speeds)} m/s with"
            f" {', '.join(f'{v:g}' for v in masses)} kg balls: calibrate one speed and ball at a time",
            source=who,
        )
    if masses and args.ball_mass_kg is not None and abs(masses[0] - args.ball_mass_kg) > 1e-9:
        raise ConfigError(
            f"--ball-mass-kg {args.ball_mass_kg:g}: the store's {args.metric} runs fired"
            f" {masses[0]:g} kg balls",
            source=who,
        )
    speed = speeds[0] if speeds else metric(args.metric).test_speed_m_s
    mass = masses[0] if masses else args.ball_mass_kg
    if speed is None or mass is None:
        raise ConfigError(
            f"a {args.metric} calibration from --data alone needs --ball-mass-kg (the runs' ball)", source=who
        )
    return speed, mass


def _print(record: dict[str, Any]) -> None:
    console = out()
    prov = record["provenance"]
    console.print(
        f"Calibration on {prov['n_bats']} bats ({record['metric']}), hoop {prov['hoop_min_hz']:.0f}-"
        f"{prov['hoop_max_hz']:.0f} Hz, data sha256 {prov['data_sha256'][:12]}..."
    )
    table = new_table(title="Variants (chosen by leave-one-out prediction error)")
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
    units = ", ".join(record["units"][n] for n in names)
    cov = new_table(title=f"Covariance of {record['variant']} ({units})")
    cov.add_column("")
    for n in names:
        cov.add_column(n, justify="right")
    for n, row in zip(names, record["covariance"], strict=True):
        cov.add_row(n, *(f"{x:.3g}" for x in row))
    console.print(cov)
    for note in record["notes"]:
        console.print(f"note: {note}")
    ball = record.get("ball")
    if ball:
        console.print(
            f"ball: {ball['file']} (lot {ball['lot'] or '-'}, {ball['variant']},"
            f" sha256 {ball['sha256'][:12]}...)"
        )
    else:
        console.print("ball: the paper's constants (no --ball)")
    console.print(
        f"chosen: {record['variant']}; bat-to-bat scatter after the fit {record['scatter']:.4f},"
        f" leave-one-out prediction RMSE {record['loo_rmse']:.4f}"
        f" (impact {record['default_location_in']:g} in from the barrel end where a row gives no location_in)"
    )


def add_parser(msub: Any) -> None:
    """`rig model calibrate` under the `rig model` subcommands."""
    from rig.population.budget import DEFAULT_MAX_SECONDS
    from rig.population.limits import DEFAULT_LOCATION_IN, MIN_BATS, MIN_HOOP_SPAN_HZ

    p = msub.add_parser(
        "calibrate",
        help="fit the barrel's m2, c2 (and a k1 scale or an offset) to measured bats",
        description=(
            "Fit the model constants the paper's ball tests leave open (barrel hoop mass m2, damping c2,"
            " and as variants a contact-stiffness scale or an offset) to a population of measured bats;"
            " choose the variant by leave-one-out prediction error. The bats come from --data, from the"
            " certified runs of a record store (--db), or both (bat ids must not repeat)."
            " Needs hoop_hz, moi_kgm2, length_in"
            f" and the metric for at least {MIN_BATS} bats spanning {MIN_HOOP_SPAN_HZ:.0f} Hz; location_in"
            f" defaults to {DEFAULT_LOCATION_IN:g} in from the barrel end. Refused (exit 2) when the"
            " residuals of the best fit show structure the model family cannot take up (a trend with"
            " hoop frequency, two groups of bats), and stopped at the time limit (--max-seconds)."
        ),
    )
    p.add_argument("--data", metavar="POPULATION", help="population file (.csv or .toml)")
    p.add_argument("--db", metavar="STORE", help="also (or only) the certified bats of this record store")
    p.add_argument("--metric", choices=cross_checked(), default="bbcor", help="metric to fit")
    p.add_argument("--output", required=True, metavar="CAL.json", help="where to write the calibration")
    p.add_argument(
        "--ball-mass-kg",
        type=float,
        metavar="KG",
        help="a BPF or USA Softball BBS calibration from --data: the runs' ball mass (a store gives it)",
    )
    p.add_argument(
        "--ball",
        metavar="BALL.json",
        help="a fitted ball (rig model fit-ball): its m1, k1, c1, a, b replace the paper's; recorded",
    )
    p.add_argument(
        "--max-seconds",
        type=_seconds,
        default=DEFAULT_MAX_SECONDS,
        help=f"stop (exit 2) when the calibration has run this long (default {DEFAULT_MAX_SECONDS:g} s)",
    )
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress lines on stderr (default: when stderr is a terminal)",
    )
    p.add_argument("--json", action="store_true", help="print the calibration record as JSON")
    p.set_defaults(handler=cmd_calibrate)


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not value > 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r}: give a time limit above 0 s")
    return value
