"""The certificate's model cross-check: calibrated, uncalibrated, or an old record's fixed tolerance."""

from __future__ import annotations

from typing import Any

from rig.report.cert_doc import Block, Figure, Para, kv
from rig.report.cert_sections import _num, _sig


def _calibrated_rows(cc: dict[str, Any]) -> list[tuple[str, str]]:
    lo, hi = (cc.get("interval") or [None, None])[:2]
    cover = cc.get("coverage")
    what = "—" if not isinstance(cover, int | float) else f"{100 * cover:g} %"
    t, dof = cc.get("t_factor"), cc.get("dof")
    parts = ", ".join(f"{name} {_sig(cc.get(name), 2)}" for name in ("u_model", "u_scatter", "u_measured"))
    result = (
        "FLAGGED: outside the interval, investigate before signing" if cc.get("flagged") else "consistent"
    )
    if cc.get("extrapolated"):
        result += " (hoop frequency outside the calibration's range: extrapolated)"
    cal = cc.get("calibration") or {}
    prov = cal.get("provenance") or {}
    params = ", ".join(f"{k} = {_sig(v, 4)}" for k, v in (cal.get("parameters") or {}).items())
    return [
        ("predicted (calibrated)", _num(cc.get("predicted"), 4)),
        (
            f"prediction interval ({what})",
            f"{_num(lo, 4)} – {_num(hi, 4)} (± t u, t = {_num(t, 3)},"
            f" Student-t with {dof} degrees of freedom)",
        ),
        (
            "its standard uncertainties",
            parts + (" (this bat's own: k = 1)" if cc.get("u_measured_known") else ""),
        ),
        ("measured", _num(cc.get("measured"), 4)),
        ("z = (measured − predicted) / u", _num(cc.get("z"), 2)),
        ("result", result),
        ("calibration", f"{cal.get('path', '—')} (named by the {cal.get('named_by', '?')})"),
        ("calibration file sha256", str(cal.get("sha256", "—"))),
        ("calibrated parameters", f"{cal.get('variant', '?')}: {params}"),
        (
            "calibration data",
            f"{prov.get('n_bats', '?')} bats, hoop {_num(prov.get('hoop_min_hz'), 0)}–"
            f"{_num(prov.get('hoop_max_hz'), 0)} Hz, data sha256 {prov.get('data_sha256', '—')}",
        ),
        ("calibration made", f"{prov.get('created_utc', '?')} with {prov.get('software', '?')}"),
    ]


def cross_check_blocks(record: dict[str, Any], fig: dict[str, Figure]) -> list[Block]:
    """The collision model's prediction next to the measured value, and the model figure.

    Three shapes: calibrated (prediction interval, consistent or flagged, the calibration's
    provenance), uncalibrated (the raw prediction, no flag) and the fixed-tolerance check of
    records made before calibrations existed.
    """
    cc = record.get("cross_check")
    if not cc:
        return [Para("No model cross-check in the record.")]
    if cc.get("predicted") is None:
        return [Para(str(cc.get("note", "no prediction"))), *([fig["model"]] if "model" in fig else [])]
    hoop = cc.get("hoop_hz")
    rows = [
        ("model", str(cc.get("model", "—"))),
        ("hoop frequency", "rigid barrel (wood)" if hoop is None else f"{hoop:g} Hz"),
    ]
    if cc.get("calibrated") is True:
        rows += _calibrated_rows(cc)
    elif cc.get("calibrated") is False:
        rows += [
            ("predicted (uncalibrated)", _num(cc.get("predicted"), 4)),
            ("measured", _num(cc.get("measured"), 4)),
            ("difference (measured − predicted)", _num(cc.get("difference"), 4)),
            ("flagged", "not judged: no calibration"),
        ]
    else:  # a record made before calibrations: a fixed tolerance
        rows += [
            ("predicted", _num(cc.get("predicted"), 4)),
            ("measured", _num(cc.get("measured"), 4)),
            ("difference (measured − predicted)", _num(cc.get("difference"), 4)),
            ("tolerance", f"± {cc.get('tolerance')}"),
            ("flagged", "YES: investigate before signing" if cc.get("flagged") else "no"),
        ]
    rows.append(("note", str(cc.get("note", ""))))
    return [kv(rows), *([fig["model"]] if "model" in fig else [])]
