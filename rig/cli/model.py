"""`rig model ...`: the collision model from the command line."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from rig.cli import calibrate, crosscheck, fit_ball
from rig.cli.common import (
    Bounds,
    add_overrides,
    check_flags,
    emit,
    new_table,
    output_file,
    positive_int,
)
from rig.cli.common import console as out
from rig.core.errors import ConfigError

# Physical ranges of the flags (docs/procedures.md, "Bounds"): a ball at 1-100 m/s (100 m/s is
# 224 mph); a barrel's hoop mode from 20 Hz (below a bat file's 200 Hz, so that the model's
# repeated contacts at low frequency can be studied: docs/contacts.md) to 10 kHz, a bat's MOI as a
# bat file bounds it; an impact point on the
# barrel, 0.05 m to 36 in (a 42 in bat's tip) from the pivot. A curve of 2000 points already
# resolves the optimum to 5 Hz over the whole hoop range and takes about two seconds.
BOUNDS: Bounds = {
    "speed": ("speed", 1.0, 100.0, "m/s"),
    "hoop": ("hoop_hz", 20.0, 10000.0, "Hz"),
    "hoop_min": ("hoop_min", 20.0, 10000.0, "Hz"),
    "hoop_max": ("hoop_max", 20.0, 10000.0, "Hz"),
    "moi": ("moi_kgm2", 0.01, 1.0, "kg m^2"),
    "impact_from_pivot": ("impact_from_pivot_m", 0.05, 0.9144, "m"),
    "points": ("points", 2, 2000, "(2000 points resolve the optimum to 5 Hz)"),
}


def _model_parent() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    add_overrides(parent, "override a model constant (m1, k1, c1, a, b, m2, c2), e.g. --set m2=0.1")
    parent.add_argument(
        "--ball",
        metavar="BALL.json",
        help="a fitted ball (rig model fit-ball): its m1, k1, c1, a, b replace the paper's",
    )
    parent.add_argument("--rtol", type=float, default=None, help="solver relative tolerance")
    parent.add_argument("--json", action="store_true", help="print JSON instead of a table")
    return parent


def _params(args: argparse.Namespace) -> Any:
    from rig.physics.params import CollisionParams, check_physical

    check_flags(args, BOUNDS)
    params = check_physical(CollisionParams.build(**dict(args.overrides)))
    if getattr(args, "ball", None):
        from rig.cli.fit_ball import load_ball

        law, _ = load_ball(args.ball)
        clash = [n for n, _ in args.overrides if n in law.constants]
        if clash:
            raise ConfigError(
                f"--set {clash[0]} and --ball exclude each other: the ball file sets {clash[0]}",
                source=f"rig model {args.model_command}",
            )
        params = law.apply(params)
    return params


def _ball_payload(args: argparse.Namespace, payload: dict[str, Any], params: Any) -> dict[str, Any]:
    """With --ball: the payload with the constants solved with and the ball file's identity."""
    if getattr(args, "ball", None):
        from rig.cli.fit_ball import load_ball
        from rig.physics.ball_law import ball_record

        law, sha = load_ball(args.ball)
        payload.setdefault("params", params.model_dump())
        payload["ball"] = ball_record(law, sha, args.ball)
    return payload


def _rtol(args: argparse.Namespace, default: float) -> float:
    return default if args.rtol is None else args.rtol


def cmd_cor(args: argparse.Namespace) -> int:
    """rig model cor: COR of one ball-barrel collision."""
    from rig.physics import fast
    from rig.physics.curve import rigid_cor
    from rig.physics.equations import Impact

    params = _params(args)
    rtol = _rtol(args, fast.DEFAULT_RTOL)
    hoop = None if args.rigid else args.hoop
    res = fast.solve(Impact(params, args.speed, hoop), rtol=rtol)
    e_rigid = res.cor if hoop is None else rigid_cor(params, args.speed)
    payload = {
        "speed_m_s": args.speed,
        "hoop_hz": hoop,
        "model": "rigid" if hoop is None else "barrel",
        "cor": res.cor,
        "cor_rigid": e_rigid,
        "efficiency": res.cor / e_rigid,
        "contact_time_s": res.contact_time_s,
        "contacts": res.contacts,
        "rtol": rtol,
        "nfev": res.nfev,
        "params": params.model_dump(),
    }
    emit(args, _ball_payload(args, payload, params), "Ball-barrel collision")
    return 0


def cmd_curve(args: argparse.Namespace) -> int:
    """rig model curve: normalized collision efficiency against hoop frequency."""
    from rig.physics import fast
    from rig.physics.curve import efficiency_curve

    output_file(args.plot, "--plot")
    params = _params(args)
    curve = efficiency_curve(
        params, args.speed, args.hoop_min, args.hoop_max, args.points, rtol=_rtol(args, fast.DEFAULT_RTOL)
    )
    if args.plot:
        from rig.report.model_plots import plot_efficiency_curve

        for path in plot_efficiency_curve(curve, args.plot):
            print(f"wrote {path}", file=sys.stderr)
    payload = {
        "speed_m_s": curve.speed,
        "cor_rigid": curve.cor_rigid,
        "optimum_hz": curve.optimum_hz,
        "optimum_efficiency": curve.optimum_efficiency,
        "optimum_interior": curve.optimum_interior,
        "rtol": curve.rtol,
        "hoop_hz": curve.hoop_hz.tolist(),
        "efficiency": curve.efficiency.tolist(),
        "cor": curve.cor.tolist(),
        "contact_time_s": curve.contact_time_s.tolist(),
        "contacts": [] if curve.contacts is None else curve.contacts.tolist(),
    }
    _ball_payload(args, payload, params)
    if args.json:
        emit(args, payload, "")
    else:
        _print_curve(curve)
        if "ball" in payload:
            b = payload["ball"]
            out().print(f"ball: {b['file']} (lot {b['lot'] or '-'}, sha256 {b['sha256'][:12]}...)")
    return 0


def _print_curve(curve: Any, rows: int = 16) -> None:
    """A readable digest of the curve: a sample of the grid with a bar per point, and the optimum."""
    import numpy as np

    idx = sorted(
        set(np.linspace(0, curve.hoop_hz.size - 1, min(rows, curve.hoop_hz.size)).round().astype(int))
    )
    lo, hi = float(curve.efficiency.min()), float(curve.efficiency.max())
    table = new_table(
        title=f"Normalized collision efficiency at {curve.speed:g} m/s (COR_rigid = {curve.cor_rigid:.4f})"
    )
    for col in ("hoop Hz", "COR", "eta", "contacts", ""):
        table.add_column(col, justify="right" if col else "left")
    contacts = np.ones(curve.hoop_hz.size, dtype=int) if curve.contacts is None else curve.contacts
    for i in idx:
        eta = float(curve.efficiency[i])
        bar = "#" * (1 + int(30 * (eta - lo) / (hi - lo or 1.0)))
        row = (f"{curve.hoop_hz[i]:.0f}", f"{curve.cor[i]:.4f}", f"{eta:.4f}", str(int(contacts[i])), bar)
        table.add_row(*row)
    console = out()
    console.print(table)
    where = "between grid points" if curve.optimum_interior else "at the end of the grid"
    console.print(
        f"optimum: {curve.optimum_hz:.1f} Hz, eta = {curve.optimum_efficiency:.4f} ({where}); "
        f"{curve.hoop_hz.size} points, rtol {curve.rtol:g}"
    )


def cmd_bat(args: argparse.Namespace) -> int:
    """rig model bat: e_A and BBCOR predicted for a bat on the pivot."""
    from rig.physics import fast
    from rig.physics.bat import PivotedBat, predict_bat

    params = _params(args)
    bat = PivotedBat.build(moi_kgm2=args.moi, impact_from_pivot_m=args.impact_from_pivot)
    hoop = None if args.rigid else args.hoop
    pred = predict_bat(params, args.speed, hoop, bat, rtol=_rtol(args, fast.DEFAULT_RTOL))
    payload: dict[str, Any] = {
        "speed_m_s": pred.speed,
        "hoop_hz": pred.hoop_hz,
        "moi_kgm2": bat.moi_kgm2,
        "impact_from_pivot_m": bat.impact_from_pivot_m,
        "e_a": pred.e_a,
        "bbcor": pred.bbcor,
        "besr": pred.besr,
        "k": pred.k,
        "effective_mass_kg": pred.effective_mass_kg,
        "contact_time_s": pred.contact_time_s,
        "definitions": {
            "e_a": "rebound speed / inbound speed, bat initially at rest",
            "bbcor": "e_a (1 + k) + k, k = m_ball Q^2 / I (founding paper Eq. 5)",
            "besr": "e_a + 1/2",
        },
    }
    _ball_payload(args, payload, params)
    if args.calibration:
        payload["calibrated"] = _calibrated(args, bat)
    elif args.measured is not None or args.u_measured is not None or args.length is not None:
        raise ConfigError(
            "--measured, --u-measured and --length need --calibration CAL.json", source="rig model bat"
        )
    if args.json or not args.calibration:
        emit(args, payload, "Pivoted-bat prediction")
        return 0
    _print_calibrated(payload["calibrated"])
    return 0


def _calibrated(args: argparse.Namespace, bat: Any) -> dict[str, Any]:
    """The calibrated model's prediction and interval for this bat (--calibration CAL.json)."""
    from rig.measure.registry import metric
    from rig.population.calfile import load_calibration
    from rig.population.crosscheck import crosscheck_at

    if args.rigid:
        raise ConfigError(
            "--calibration needs --hoop: the calibration is of the hoop-mode model", source="rig model bat"
        )
    if args.overrides:
        raise ConfigError(
            "--set and --calibration exclude each other: the calibration sets m2, c2", source="rig model bat"
        )
    cal = load_calibration(args.calibration)
    if args.ball:
        from rig.cli.fit_ball import check_calibration_ball

        check_calibration_ball(cal, args.ball, "rig model bat")
    if abs(args.speed - cal.speed_m_s) > 1e-9:
        raise ConfigError(
            f"--speed {args.speed:g}: the calibration predicts at {cal.speed_m_s:g} m/s",
            source="rig model bat",
        )
    entry = metric(cal.metric)
    if entry.needs_length and args.length is None:
        raise ConfigError(
            f"a {entry.label} calibration needs --length (in): the swing model uses it",
            source="rig model bat",
        )
    length = 33.0 if args.length is None else args.length  # a metric that needs no length ignores it
    check = crosscheck_at(
        cal,
        args.hoop,
        bat.moi_kgm2,
        bat.impact_from_pivot_m,
        length,
        args.measured,
        args.u_measured,
        args.coverage,
    )
    out = check.as_dict()
    out["calibration"] = args.calibration
    out["calibration_variant"] = cal.variant
    out["calibration_parameters"] = dict(cal.parameters)
    out["calibration_provenance"] = cal.provenance.model_dump()
    out["calibrated_range"] = cal.provenance.range_text()
    out["bat_id"] = "(command line)"
    return out


def _print_calibrated(c: dict[str, Any]) -> None:
    console = out()
    prov = c["calibration_provenance"]
    lo, hi = c["interval"]
    console.print(
        f"calibrated {c['metric']} at {c['hoop_hz']:.0f} Hz: {c['predicted']:.4f},"
        f" {100 * c['coverage']:g} % prediction interval {lo:.4f} - {hi:.4f}"
        f" (t = {c['t_factor']:.3f}, {c['dof']} dof; u_model {c['u_model']:.4f},"
        f" u_scatter {c['u_scatter']:.4f}, u_measured {c['u_measured']:.4f})"
    )
    if c["extrapolated"]:
        console.print(f"note: outside the calibrated range ({c['calibrated_range']}): extrapolated")
    if c["measured"] is not None:
        verdict = "FLAGGED: outside the interval" if c["flagged"] else "consistent"
        console.print(f"measured {c['measured']:.4f}, z = {c['z']:+.2f}: {verdict}")
    console.print(
        f"calibration {c['calibration']} ({c['calibration_variant']}): {prov['n_bats']} bats,"
        f" data sha256 {prov['data_sha256'][:12]}..., {prov['created_utc']}, {prov['software']}"
    )


MODEL_DOC = "The ball-barrel collision model (founding paper, Eqs. 1-2)."


def add_parsers(sub: Any) -> None:
    """`rig model cor|curve|bat|calibrate|crosscheck|fit-ball`."""
    model = sub.add_parser(
        "model",
        help="the ball-barrel collision model",
        description="The ball-barrel collision model (founding paper, Eqs. 1-2).",
    )
    msub = model.add_subparsers(dest="model_command", required=True, metavar="MODEL_COMMAND")
    parent = _model_parent()

    p = msub.add_parser("cor", parents=[parent], help="COR of one collision")
    p.add_argument("--speed", type=float, required=True, help="inbound ball speed, m/s (1-100)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--hoop", type=float, help="hoop frequency of the barrel, Hz (20-10000)")
    g.add_argument("--rigid", action="store_true", help="a rigid barrel (f_hoop -> infinity)")
    p.set_defaults(handler=cmd_cor)

    p = msub.add_parser("curve", parents=[parent], help="efficiency eta(f) = COR(f)/COR_rigid")
    p.add_argument("--speed", type=float, required=True, help="inbound ball speed, m/s (1-100)")
    p.add_argument("--hoop-min", type=float, required=True, help="lowest hoop frequency, Hz (20-10000)")
    p.add_argument("--hoop-max", type=float, required=True, help="highest hoop frequency, Hz (20-10000)")
    p.add_argument("--points", type=positive_int, default=200, help="grid points, evenly spaced (2-2000)")
    p.add_argument("--plot", metavar="FILE", help="write a plot (PNG and SVG beside it)")
    p.set_defaults(handler=cmd_curve)

    p = msub.add_parser("bat", parents=[parent], help="e_A and BBCOR of a bat on the pivot")
    p.add_argument("--speed", type=float, required=True, help="inbound ball speed, m/s (1-100)")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--hoop", type=float, help="hoop frequency of the barrel, Hz (20-10000)")
    g.add_argument("--rigid", action="store_true", help="a rigid barrel (a wood bat)")
    p.add_argument("--moi", type=float, required=True, help="MOI about the pivot, kg m^2 (0.01-1)")
    p.add_argument(
        "--impact-from-pivot", type=float, required=True, help="pivot-to-impact distance Q, m (0.05-0.9144)"
    )
    p.add_argument(
        "--calibration",
        metavar="CAL.json",
        help="also the calibrated prediction and its interval (rig model calibrate)",
    )
    p.add_argument(
        "--coverage", type=float, default=0.95, help="the interval's coverage (with --calibration)"
    )
    p.add_argument("--measured", type=float, help="a measured value to cross-check (with --calibration)")
    p.add_argument("--u-measured", type=float, help="its standard uncertainty, k = 1 (with --calibration)")
    p.add_argument("--length", type=float, help="bat length, in (with a BBS calibration)")
    p.set_defaults(handler=cmd_bat)

    calibrate.add_parser(msub)
    crosscheck.add_parser(msub)
    fit_ball.add_parser(msub)
