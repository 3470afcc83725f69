"""`rig model fit-ball`: fit the ball's contact law to CCOR against speed; writes BALL.json."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rig.cli.common import add_overrides, new_table, output_file, refuse_overwriting_store
from rig.cli.common import console as out
from rig.core.errors import ConfigError

if TYPE_CHECKING:
    from rig.ball.data import CcorData

WHO = "rig model fit-ball"
FIXED = ("m1", "k1", "c1")  # what --set may fix (a and b are always fitted)
PLOT_SPEEDS = 120


def gather(data: str | None, db: str | None, lot: str | None) -> tuple[CcorData, tuple[str, ...]]:
    """The CCOR points of a CSV file or of a store's lot tests, and the store runs they come from.

    One source per fit: --data and --db together are refused. Combined, a file exported from the
    same tests would count every hit twice (the stated sigma shrinking by sqrt 2 with no new
    information), a ball id in both would merge two balls into one leave-out group, and the
    provenance could not say which file or which runs the law rests on.
    """
    from rig.ball.data import load_ccor_csv

    if data and db:
        raise ConfigError(
            "give --data CCOR.csv or --db STORE --lot LOT, not both: a fit reads one source", source=WHO
        )
    if not data and not db:
        raise ConfigError("give --data CCOR.csv or --db STORE --lot LOT", source=WHO)
    if data:
        return load_ccor_csv(data), ()
    if not lot:
        raise ConfigError("--db needs --lot LOT: which ball lot's ccor tests to fit", source=WHO)
    from rig.ball.source import ccor_data_from_store
    from rig.cli.common import shown_db
    from rig.store import Store

    assert db is not None  # neither --data nor --db was refused above
    with Store.open(db, create=False) as store:
        got = ccor_data_from_store(store, lot, f"store {shown_db(db)}, lot {lot}")
    return got.data, got.runs


def _base(overrides: list[tuple[str, float]]) -> tuple[Any, dict[str, str]]:
    """The fixed constants (the paper's, or --set) and where each comes from."""
    from rig.physics.params import DEFAULT_PARAMS, CollisionParams, check_physical

    values = dict(overrides)
    bad = [n for n in values if n not in FIXED]
    if bad:
        raise ConfigError(
            f"--set {bad[0]}: only {', '.join(FIXED)} can be fixed (a and b are fitted)", source=WHO
        )
    params = check_physical(CollisionParams.build(**{**DEFAULT_PARAMS.model_dump(), **values}))
    return params, {n: f"--set {n}={v:g} (the lab's value)" for n, v in values.items()}


def cmd_fit_ball(args: argparse.Namespace) -> int:
    """rig model fit-ball: the fit, its covariance, scatter and leave-one-out error; writes BALL.json."""
    from rig.ball.fit import fit_ball
    from rig.ball.record import ball_law

    output = output_file(args.output, "--output")
    assert output is not None  # a required flag
    output_file(args.plot, "--plot")
    csv = Path(args.data) if args.data else None
    if csv is not None and output.exists() and csv.exists() and output.resolve() == csv.resolve():
        raise ConfigError("--output would overwrite the data file (--data)", source=str(output))
    if args.db:
        refuse_overwriting_store(output, args.db)
    base, sources = _base(args.overrides)
    data, runs = gather(args.data, args.db, args.lot)
    result = fit_ball(data.points, base)
    law = ball_law(result, data.blob, data.name, lot=args.lot, fixed_sources=sources, runs=runs)
    law.save(output)
    if args.plot:
        import numpy as np

        from rig.ball.fit import model_ccor
        from rig.report.ball_plots import plot_ccor_fit

        speeds = np.linspace(law.provenance.speed_min_m_s, law.provenance.speed_max_m_s, PLOT_SPEEDS)
        for path in plot_ccor_fit(law, speeds, model_ccor(law.params, speeds), args.plot):
            print(f"wrote {path}", file=sys.stderr)
    if args.json:
        json.dump(law.model_dump(mode="json"), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        _print(law)
    print(f"wrote {output}", file=sys.stderr)
    if args.db:  # fitted on the lot's own tests: the lot's ball law from now on
        from rig.ball_rules import record_lot_law
        from rig.cli.common import shown_db
        from rig.store import Store

        with Store.open(args.db, create=False) as store:
            entry, sha = record_lot_law(store, args.lot, str(output))
        print(
            f"recorded as lot {args.lot}'s ball law in {shown_db(args.db)} (entry {entry.seq}, sha256"
            f" {sha[:12]}): rig certify --ball-lot {args.lot} uses it; rig balls law {args.lot} writes it",
            file=sys.stderr,
        )
    return 0


def load_ball(path: str) -> tuple[Any, str]:
    """A ball file (`--ball`) and its sha256; ConfigError names the file and the cause."""
    from rig.physics.ball_law import BallLaw

    return BallLaw.read(path)


def check_calibration_ball(cal: Any, ball: str, who: str) -> None:
    """Refuse a ball other than the one the calibration was made with (the paper's when it names none).

    The calibration's m2, c2 (and k1 scale or offset) were fitted with its ball's constants; a
    prediction with another ball would mix a barrel fitted for one ball law with another law, an
    error no interval covers. Recalibrate with the new ball instead.
    """
    law, sha = load_ball(ball)
    recorded = cal.ball
    if recorded is None:
        raise ConfigError(
            f"--ball {ball}: the calibration was made with the paper's ball, not this one;"
            " recalibrate with --ball or drop --ball",
            source=who,
        )
    from rig.protocols.verdict import same_law

    if not same_law(dict(recorded["constants"]), dict(law.constants)):
        raise ConfigError(
            f"--ball {ball} (lot {law.lot or '-'}, sha256 {sha[:12]}) differs from the calibration's ball"
            f" (lot {recorded.get('lot') or '-'}, sha256 {str(recorded.get('sha256'))[:12]});"
            " recalibrate with this ball or drop --ball",
            source=who,
        )


def why_chosen(law: Any) -> str:
    """Why the chosen variant was chosen, in one sentence."""
    identified = [v for v in law.variants if v["identified"]]
    left = [v["variant"] for v in law.variants if not v["identified"]]
    text = f"chosen: {law.variant} (LOO RMSE {law.loo_rmse:.5f})"
    others = [v for v in identified if v["variant"] != law.variant]
    if others:
        text += "; " + ", ".join(f"{v['variant']} LOO RMSE {v['loo_rmse']:.5f}" for v in others)
        text += ": the simplest within one standard error of the best"
    elif not left:
        text += ": the only variant"
    if left:
        text += f"; not identified by these data: {', '.join(left)}"
    return text


def _print(law: Any) -> None:
    console = out()
    prov = law.provenance
    console.print(
        f"Ball law from {prov.n_points} CCOR points ({prov.n_balls} balls, {prov.n_speeds} speeds,"
        f" {prov.speed_min_m_s:.1f}-{prov.speed_max_m_s:.1f} m/s)"
        + (f", lot {prov.lot}" if prov.lot else "")
        + f", data sha256 {prov.data_sha256[:12]}..."
    )
    if prov.runs:
        console.print(f"from the store's ccor test run(s): {', '.join(prov.runs)}")
    table = new_table(title="Variants (chosen by leave-one-out error)")
    for col in ("variant", "parameters (+- 1 sigma)", "scatter", "LOO RMSE", "condition", ""):
        table.add_column(col)
    for v in law.variants:
        params = ", ".join(
            f"{k} = {val:.5g}" + ("" if v["uncertainty"][k] is None else f" +- {v['uncertainty'][k]:.2g}")
            for k, val in v["parameters"].items()
        )
        loo = "not identified" if v["loo_rmse"] is None else f"{v['loo_rmse']:.5f}"
        cond = "-" if v["condition_number"] is None else f"{v['condition_number']:.3g}"
        mark = "chosen" if v["variant"] == law.variant else ""
        table.add_row(v["variant"], params, f"{v['scatter']:.5f}", loo, cond, mark)
    console.print(table)
    names = list(law.parameters)
    cov = new_table(title=f"Covariance of {law.variant}")
    cov.add_column("")
    for n in names:
        cov.add_column(n, justify="right")
    for n, row in zip(names, law.covariance, strict=True):
        cov.add_row(n, *(f"{x:.4g}" for x in row))
    console.print(cov)
    for n in names:
        console.print(f"{n} = {law.parameters[n]:.5g} +- {law.uncertainty[n]:.2g} (1 sigma)")
    if law.correlation_ab is not None:
        console.print(f"correlation a-b: {law.correlation_ab:+.6f}")
    fixed = "; ".join(f"{n} = {law.constants[n]:.6g} from {src}" for n, src in prov.fixed.items())
    console.print(f"fixed: {fixed}")
    console.print(f"weighting: {law.weighting}")
    for note in law.notes:
        console.print(f"note: {note}")
    console.print(
        f"residual scatter {law.scatter:.5f} CCOR ({law.dof} degrees of freedom),"
        f" leave-one-out RMSE {law.loo_rmse:.5f}"
    )
    console.print(why_chosen(law))


def add_parser(msub: Any) -> None:
    """`rig model fit-ball` under the `rig model` subcommands."""
    from rig.ball.limits import MIN_SPEED_RATIO, MIN_SPEEDS

    p = msub.add_parser(
        "fit-ball",
        help="fit the ball's contact law (a, b; k1, c1 where identified) to CCOR against speed",
        description=(
            "Fit the ball law's exponents a and b (and, as variants, c1 or k1 and c1) to the cylindrical"
            " COR measured against a rigid cylinder at several inbound speeds (the founding paper's Fig. 3);"
            " the model's CCOR is the COR of the ball on a rigid immovable surface. The variant is chosen"
            " by leave-one-out error. CSV columns: speed_m_s, ccor, optional u_ccor and ball_id; or, instead"
            " of a file, --db STORE --lot LOT: the valid hits of the lot's finished ccor tests in the store;"
            " the law is then recorded in the store as the lot's (rig certify --ball-lot LOT uses it)."
            f" Needs at least {MIN_SPEEDS} distinct speeds, the highest at least {MIN_SPEED_RATIO:g} x the"
            " lowest."
        ),
    )
    p.add_argument("--data", metavar="CCOR.csv", help="CCOR points (speed_m_s, ccor[, u_ccor, ball_id])")
    p.add_argument(
        "--db",
        metavar="STORE",
        help="instead of --data: the valid hits of --lot's finished ccor tests in this record store",
    )
    p.add_argument("--lot", metavar="LOT", help="the ball lot (recorded; with --db, whose tests to read)")
    add_overrides(p, "fix m1, k1 or c1 at the lab's value (default: the paper's), e.g. --set m1=0.1445")
    p.add_argument("--output", required=True, metavar="BALL.json", help="where to write the ball law")
    p.add_argument("--json", action="store_true", help="print the ball-law record as JSON")
    p.add_argument("--plot", metavar="FIG", help="draw measured and model CCOR against speed (PNG and SVG)")
    p.set_defaults(handler=cmd_fit_ball)
