"""The certificate's balls: the lot and its terms, the ball law, each valid hit's ball and correction,
and the ball's part of the budget.

From the record alone: the ball terms RunStarted recorded (`record["ball"]`, the fields of
rig.protocols.ball_terms.BallTerms), each shot's ball and its hits before it (`raw`), and the verdict's
`ball` (its corrections per valid hit, in the order of the hits, and its budget terms). A record
made before any of these were kept has no Balls section (it reports as it did when it was made),
and its valid hits show the ball's number.
"""

from __future__ import annotations

from typing import Any

from rig.report.cert_doc import Block, Heading, Para, Table, kv
from rig.report.cert_plots import certification_hits, metric_label, unit_suffix
from rig.report.cert_sections import _num, _sig, ball_text

NO_LOT = "no lot named: assumed defaults [U]"
PAPER_LAW = "the founding paper's constants"
_LAW_ORDER = ("m1", "k1", "c1", "a", "b")  # as a ball file (BALL.json) lists them; the store sorts keys


def _signed(x: Any, decimals: int) -> str:
    return "—" if not isinstance(x, int | float) else f"{x + 0.0:+.{decimals}f}"  # + 0.0: no '-0'


def _is_num(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _law_text(terms: dict[str, Any]) -> str:
    if "law" not in terms:
        return "—"
    law = terms.get("law")
    if not law:
        return PAPER_LAW
    names = [k for k in _LAW_ORDER if k in law] + sorted(k for k in law if k not in _LAW_ORDER)
    text = "fitted ball law: " + ", ".join(f"{k} = {_sig(law[k], 5)}" for k in names)
    if terms.get("law_sha256"):  # recorded since the lot's law could be named by the lot
        text += f" ({terms.get('law_from') or 'ball file'}, sha256 {str(terms['law_sha256'])[:12]})"
    return text


def _lot_text(terms: dict[str, Any]) -> str:
    if terms.get("lot"):
        return str(terms["lot"])
    if terms.get("wear_measured") or terms.get("conditions_measured"):
        return "no lot named"
    return NO_LOT


def _sensitivity(value: Any, u: Any, per: str) -> str:
    u_text = "—" if u is None else f"{float(u):.2g}"  # a measured slope's u can be 1e-6
    return f"{_signed(value, 6)} ± {u_text} plate COR per {per}"


def _wear_text(terms: dict[str, Any]) -> str:
    slope = _sensitivity(terms.get("wear_per_hit"), terms.get("wear_per_hit_u"), "hit")
    if terms.get("wear_measured"):
        return f"corrected: {slope}, measured on the lot; the slope's u is budgeted"
    return f"not corrected: {slope}, stated, not measured on the lot; the whole effect is budgeted"


def _air_text(terms: dict[str, Any]) -> str:
    sens = (
        f"{_sensitivity(terms.get('cor_per_c'), terms.get('cor_per_c_u'), '°C')}, "
        f"{_sensitivity(terms.get('cor_per_pct_rh'), terms.get('cor_per_pct_rh_u'), '% RH')}"
    )
    if terms.get("conditions_measured"):
        cov = terms.get("air_cov")
        if cov and cov[0] > 0 and cov[2] > 0:
            r = cov[1] / (cov[0] * cov[2]) ** 0.5
            sens += (
                f" (correlation {r:+.2f}: the lot's tests pin their combination along the lab's swing of"
                " air, and the budget uses the full covariance)"
            )
        return f"corrected to the nominal: {sens}, measured; their u is budgeted"
    if "assumed" in str(terms.get("source", "")) and not terms.get("lot"):
        return f"not corrected: {sens}, assumed defaults [U]; the whole effect is budgeted"
    return f"not corrected: {sens}, stated, not measured; the whole effect is budgeted"


def _terms_rows(record: dict[str, Any], terms: dict[str, Any]) -> list[tuple[str, str]]:
    """The lot, the source of its terms, the ball law, the nominal condition, what is corrected."""
    proc_ball = (record.get("procedure") or {}).get("ball") or {}
    rows = [
        ("lot", _lot_text(terms)),
        ("source of the ball terms", str(terms.get("source") or "—")),
        ("ball law in use", _law_text(terms)),
    ]
    if _is_num(terms.get("plate_cor")):
        rows.append(
            (
                "lot's COR on the flat plate at 60 mph (ball-cor; at the tests' mean hit count"
                + (", its nominal air)" if terms.get("conditions_measured") else ", the latest test's air)"),
                _num(terms["plate_cor"], 4),
            )
        )
    if _is_num(proc_ball.get("mass_kg")) or _is_num(proc_ball.get("replace_after_hits")):
        rows.append(
            (
                "procedure's ball",
                f"{_num(proc_ball.get('mass_kg'), 3)} kg; a new ball after "
                f"{proc_ball.get('replace_after_hits', '—')} hits",
            )
        )
    rows += [
        (
            "nominal condition (conditioning)",
            f"{_num(terms.get('temp_c'), 1)} °C, {_num(terms.get('rh_pct'), 0)} % RH",
        ),
        ("wear (per hit of a ball)", _wear_text(terms)),
        ("the lab's air", _air_text(terms)),
        (
            "spread between the lot's balls",
            f"SD {_num(terms.get('sd_between_balls'), 4)} plate COR: never corrected (a ball's own COR is "
            "not known), budgeted per ball used",
        ),
    ]
    return rows


def _hit_rows(
    record: dict[str, Any], vb: dict[str, Any], d: int
) -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...], list[Block]]:
    """Each valid hit of the result: its ball and hit count, the air at it, its correction."""
    v = record.get("verdict") or {}
    hits = certification_hits(record)
    corrections = list(vb.get("corrections") or [])
    corrected = list(v.get("hits") or [])
    notes: list[Block] = []
    if len(hits) != len(corrections):
        notes.append(
            Para(
                f"The record's {len(hits)} valid hits and the verdict's {len(corrections)} corrections do "
                "not pair up: the corrections are listed in the verdict's order, without their shots."
            )
        )
        hits = [{} for _ in corrections]
    if len(corrected) != len(corrections):
        corrected = [None] * len(corrections)
    air = any(_is_num(s.get("temperature_c")) for s in hits)
    name = carried_label(v)
    bpf = v.get("bpf") if isinstance(v.get("bpf"), dict) else None
    cor = bpf.get("ball_cor") if bpf else None
    headers = (
        "shot",
        "ball",
        *(("air at the shot",) if air else ()),
        f"{name} measured",
        "correction",
        f"{name} corrected",
        *((f"BPF = corrected / ball COR {_num(cor, 4)}",) if bpf else ()),
    )
    rows = tuple(
        (
            str(s.get("index", "?")),
            ball_text(s.get("raw")) if s else "—",
            *(
                (f"{_num(s.get('temperature_c'), 1)} °C, {_num(s.get('humidity_pct'), 0)} % RH",)
                if air
                else ()
            ),
            _num((s.get("metrics") or {}).get("bbcor") if bpf else s.get("metric"), d),
            _signed(c, d + 1),
            _num(after * cor if bpf and _is_num(after) and _is_num(cor) else after, d),
            *((_num(after, d),) if bpf else ()),
        )
        for s, c, after in zip(hits, corrections, corrected, strict=True)
    )
    return headers, rows, notes


def carried_label(v: dict[str, Any]) -> str:
    """What the ball's corrections and terms are in: the metric, or a BPF's BBCOR (its numerator)."""
    return "BBCOR (pivoted)" if isinstance(v.get("bpf"), dict) else metric_label(v.get("metric"))


def _how(terms: dict[str, Any], measured: str, thing: str) -> str:
    """Which part of an effect a budget term is: the u of a measured sensitivity, or the whole effect."""
    if not terms:
        return ""
    return f" (u of the measured {thing})" if terms.get(measured) else f" (the stated {thing}: whole effect)"


def _budget_rows(terms: dict[str, Any], vb: dict[str, Any], v: dict[str, Any]) -> list[tuple[str, str, str]]:
    what = {
        "u_wear": "wear within each ball" + _how(terms, "wear_measured", "slope"),
        "u_conditions": "the lab's air against the nominal"
        + _how(terms, "conditions_measured", "sensitivities"),
        "u_spread": "spread between the lot's balls (hits on one ball share its offset)",
        "u_ratio": "the model ratio g (on the corrections)",
    }
    rows = [(key.removeprefix("u_"), words, _sig(vb.get(key))) for key, words in what.items() if key in vb]
    if "u" in vb:
        rows.append(("ball", "the ball's terms combined", _sig(vb["u"])))
    if isinstance(v.get("bpf"), dict):  # BBCOR's terms: the BPF section combines them with the COR's
        return rows
    if "u_measurement" in vb:
        rows.append(
            (
                "measurement",
                "the measurement without the ball (budget above, scatter)",
                _sig(vb["u_measurement"]),
            )
        )
    if _is_num(v.get("u")) and "u" in vb:
        rows.append(("result", "the measurement and the ball combined: the result's u", _sig(v["u"], 3)))
    return rows


def ball_blocks(record: dict[str, Any], decimals: int) -> list[Block]:
    """The balls of the run: lot, terms and law; each valid hit's correction; the ball's budget terms."""
    recorded, v = record.get("ball"), record.get("verdict") or {}
    terms: dict[str, Any] = recorded if isinstance(recorded, dict) else {}
    vb: dict[str, Any] = v["ball"] if isinstance(v.get("ball"), dict) else {}
    if not terms and not vb:  # a record made before the ball terms: it reports as it always did
        return []
    out: list[Block] = [Heading("Balls")]
    name = metric_label(v.get("metric") or (record.get("procedure") or {}).get("standard"))
    out.append(
        Para(
            f"The certified {name} is meant for a new ball of the lot's nominal condition. The balls fired "
            "differ from it by their wear, the lab's air and the spread between the lot's balls; each is "
            "corrected where the lab measured its sensitivity on the lot, and budgeted."
        )
    )
    if terms:
        out.append(kv(_terms_rows(record, terms)))
    else:
        out.append(Para("The ball terms the run used (lot, source, law) are not in this record."))
    if not vb:
        no = "No verdict" if not v else "The verdict has no ball terms"
        out.append(Para(f"{no}: no hit is corrected for its ball and the ball is not in the budget."))
        return out
    bpf = isinstance(v.get("bpf"), dict)
    unit = "" if bpf else unit_suffix(v.get("metric"))
    name = carried_label(v)
    g_text = f"ratio g = d{name}/d(plate COR) = {_sig(vb.get('g'), 4)}{unit}" if "g" in vb else ""
    balls = ", ".join(str(b) for b in vb.get("balls") or []) or "—"
    corrections = [c for c in vb.get("corrections") or [] if _is_num(c)]
    mean_c = sum(corrections) / len(corrections) if corrections else None
    headers, rows, notes = _hit_rows(record, vb, decimals + 1)
    out += [
        Heading("Each valid hit's ball", 3),
        Para(
            f"Balls of the result: {balls}. A change of the ball's COR on the plate is carried to {name} by "
            f"the collision model's {g_text or 'ratio g (not recorded)'}. Corrected = measured + correction; "
            f"the result is the mean of the corrected hits (mean correction {_signed(mean_c, decimals + 2)}"
            f"{unit})."
        ),
        *notes,
        Table(headers, rows),
        Heading("The ball in the budget", 3),
        Table(
            ("term", "what", f"standard u ({name}{unit and ',' + unit})"), tuple(_budget_rows(terms, vb, v))
        ),
    ]
    if bpf:
        out.append(
            Para(
                "These terms are the hits' BBCOR's. In the BPF (section Bat performance factor) the spread "
                "and the ratio stay the hits' own; the wear per hit and the air's sensitivities also move "
                "the lot's COR, by one value each, so each enters the BPF once, with both offsets."
            )
        )
    return out
