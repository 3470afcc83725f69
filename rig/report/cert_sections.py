"""Certificate sections built from the shots and the verdict: scan, hits, rejects, operator, budget, model."""

from __future__ import annotations

import re
from typing import Any

from rig.core import events as ev
from rig.measure import registry
from rig.report.cert_doc import Block, Figure, Heading, Para, Table
from rig.report.cert_plots import budget_scale, certification_hits, metric_label, unit_suffix
from rig.report.cert_shares import SCATTER, Term, result_terms, what

_PROMPT_SEQ = re.compile(r"-\d+$")  # ring-before-12 -> ring-before
_INPUTS = {
    "I": "MOI about the pivot (kg m²; its own budget below)",
    "Q": "pivot-to-impact distance (m)",
    "m_ball": "ball mass (kg)",
    "Cd_in": "drag coefficient, inbound ball (drag correction)",
    "Cd_out": "drag coefficient, rebounding ball (drag correction)",
    "rho": "lab air density (kg/m³; drag correction)",
}


def _num(x: Any, decimals: int) -> str:
    return "—" if not isinstance(x, int | float) else f"{x:.{decimals}f}"


def _ball_clause(v: dict[str, Any], ball: dict[str, Any] | None) -> str:
    """How the ball's terms join the result: added (a metric's), or with the lot's COR (a BPF's, in BBCOR)."""
    if not ball:
        return "."
    if isinstance(v.get("bpf"), dict):
        return (
            f", the ball's terms (in BBCOR, u = {_sig(ball.get('u'), 3)}, see Balls) and the lot's COR, "
            "combined as section Bat performance factor shows."
        )
    return f", and the ball's terms, u = {_sig(ball.get('u'), 3)} (see Balls)."


def _sig(x: Any, digits: int = 2) -> str:
    return "—" if not isinstance(x, int | float) else f"{x:.{digits}g}"


def _reasons(shot: dict[str, Any]) -> str:
    return (
        "; ".join(f"{r.get('code', '?')}: {r.get('message', '')}" for r in shot.get("reasons") or []) or "—"
    )


def ball_text(raw: dict[str, Any] | None) -> str:
    """A shot's ball and its hit count with this shot ('LOT-02 (hit 3)'); an older record's ball number."""
    raw = raw or {}
    ball, before = raw.get("ball"), raw.get("ball_hits")
    if ball:
        return f"{ball} (hit {before + 1})" if isinstance(before, int) else str(ball)
    number = raw.get("ball_number")
    return "—" if number is None else str(number)


def _purpose(shot: dict[str, Any]) -> str:
    return {"scan": "scan", "valid": "certification"}.get(
        str(shot.get("purpose")), str(shot.get("purpose", "?"))
    )


def _bracket_blocks(record: dict[str, Any]) -> list[Block]:
    """Whether the maximum was bracketed, and the scan's extensions that looked for it."""
    loc = record.get("location") or {}
    out: list[Block] = []
    ext = [f"{x['from_barrel_end_in']:g}" for x in record.get("scan_extensions") or []]
    if ext:
        out.append(
            Para(
                f"The scan was extended to {', '.join(ext)} in from the tip (within the procedure's "
                "scan.extend_in and the bat's reach) because its highest mean was at an edge."
            )
        )
    if loc.get("bracketed") is True:
        out.append(Para("The location of maximum performance is bracketed: lower means on both sides."))
    elif loc.get("bracketed") is False:
        out.append(
            Para(
                f"The location of maximum performance is NOT bracketed (highest mean at the edge of the "
                f"allowed scan); certified there on the word of {loc.get('accepted_by', '?')} (recorded)."
            )
        )
    return out


def _valid_text(record: dict[str, Any], name: str) -> str:
    """What the valid-hits table shows, and how the result follows from it."""
    corrections = ((record.get("verdict") or {}).get("ball") or {}).get("corrections") or []
    if any(c for c in corrections):
        return (
            f"Valid shots as measured; those marked 'yes' are the hits whose mean {name}, each hit "
            "corrected for its ball (see Balls), is the result."
        )
    return f"Valid shots; those marked 'yes' are the hits whose mean {name} is the result."


def shot_blocks(record: dict[str, Any], decimals: int, fig: dict[str, Figure]) -> list[Block]:
    """Location scan, valid hits, and every shot that did not count, with its reasons."""
    shots = record.get("shots") or []
    name = metric_label((record.get("procedure") or {}).get("standard"))
    d = decimals + 1  # one place finer than the result
    loc = record.get("location") or {}
    scan, chosen = loc.get("scan") or {}, loc.get("from_barrel_end_in")
    scan_shots = [s for s in shots if s.get("purpose") == "scan"]
    places = sorted(
        {float(k) for k in scan} | {float(s["location_in"]) for s in scan_shots if "location_in" in s}
    )
    rows = []
    for x in places:
        here = [s for s in scan_shots if s.get("location_in") == x]
        q = next(
            (
                s["raw"]["impact_from_pivot_m"]
                for s in here
                if (s.get("raw") or {}).get("impact_from_pivot_m")
            ),
            None,
        )
        counted = [str(s["index"]) for s in here if s.get("status") == "valid"]
        mean = next((v for k, v in scan.items() if float(k) == x), None)
        rows.append(
            (
                f"{x:g}",
                _num(q, 4),
                ", ".join(counted) or "—",
                _num(mean, d),
                "◀ chosen" if x == chosen else "",
            )
        )
    out: list[Block] = [Heading("Location scan")]
    if rows:
        out.append(Table(("from barrel end (in)", "Q (m)", "valid shots", f"mean {name}", ""), tuple(rows)))
    else:
        out.append(Para("No location scan recorded."))
    out += _bracket_blocks(record)
    out += [fig["scan"]] if "scan" in fig else []
    used = {s["index"] for s in certification_hits(record)}
    valid = [s for s in shots if s.get("status") == "valid"]
    out += [
        Heading("Valid hits"),
        Para(_valid_text(record, name)),
        Table(
            (
                "shot",
                "purpose",
                "location (in)",
                "ball",
                "inbound (m/s)",
                "rebound (m/s)",
                name,
                "u",
                "in result",
                "notes",
            ),
            tuple(
                (
                    str(s["index"]),
                    _purpose(s),
                    f"{s.get('location_in', '?'):g}",
                    ball_text(s.get("raw")),
                    _num(s.get("inbound_speed_m_s"), 3),
                    _num(s.get("rebound_speed_m_s"), 3),
                    _num(s.get("metric"), d),
                    _sig(s.get("u")),
                    "yes" if s["index"] in used else "",
                    _reasons(s) if s.get("reasons") else "",
                )
                for s in valid
            ),
        ),
    ]
    out += [fig["hits"]] if "hits" in fig else []
    rejected = [s for s in shots if s.get("status") != "valid"]
    status_text = {"invalid": "invalid: re-shot", "lost": "lost: no result", "fired": "fired, not evaluated"}
    out += [
        Heading("Invalid and lost shots"),
        Table(
            ("shot", "purpose", "location (in)", "status", "inbound (m/s)", "rebound (m/s)", "reasons"),
            tuple(
                (
                    str(s["index"]),
                    _purpose(s),
                    f"{s.get('location_in', '?'):g}",
                    status_text.get(str(s.get("status")), "requested, no outcome recorded"),
                    _num(s.get("inbound_speed_m_s"), 3),
                    _num(s.get("rebound_speed_m_s"), 3),
                    _reasons(s),
                )
                for s in rejected
            ),
        )
        if rejected
        else Para("None."),
        Para(
            f"Shots in the record: {len(shots)} ({len(valid)} valid, "
            f"{sum(s.get('status') == 'invalid' for s in shots)} invalid, "
            f"{sum(s.get('status') == 'lost' for s in shots)} lost, "
            f"{sum(s.get('status') not in ('valid', 'invalid', 'lost') for s in shots)} without an outcome); "
            "every one is listed above."
        ),
    ]
    return out


_GIVEN_COLUMNS = (  # how a yes was given (protocols.control), as the certificate names it
    ("asked", "yes, on its own prompt"),
    ("with", "yes, with another answer"),
    ("script", "yes, by the script"),
)


def operator_blocks(record: dict[str, Any]) -> list[Block]:
    """Prompts grouped by kind with their answers; anything but 'yes' listed one by one.

    A record that keeps how each answer was given (OperatorAnswered.given) splits the yes answers:
    on the prompt's own question, with another prompt's answer (a lab's one key), by a script; an
    inspection counts as made only in the first. Older records keep the one yes column."""
    groups: dict[str, dict[str, Any]] = {}
    texts: dict[str, str] = {}
    odd: list[tuple[str, ...]] = []
    carried: list[tuple[str, ...]] = []
    answers = [e for e in record.get("operator") or [] if e.get("kind") != ev.OPERATOR_PROMPTED]
    split = any("given" in e for e in answers)
    for e in record.get("operator") or []:
        pid = str(e.get("prompt_id", "?"))
        g = groups.setdefault(
            _PROMPT_SEQ.sub("", pid),
            {
                "text": "",
                "asked": 0,
                "yes": 0,
                "no": 0,
                "who": set(),
                "given": dict.fromkeys(("asked", "with", "script", None), 0),
            },
        )
        if e.get("kind") == ev.OPERATOR_PROMPTED:
            g["asked"] += 1
            g["text"] = g["text"] or str(e.get("text", ""))
            texts[pid] = str(e.get("text", ""))
            continue
        g["who"].add(str(e.get("who", "?")))
        if e.get("answer") is True:
            g["yes"] += 1
            given = e.get("given")
            g["given"][given if given in g["given"] else None] += 1
            if given == "with":
                carried.append(
                    (str(e.get("t_utc", "")), pid, texts.get(pid, ""), str(e.get("with_prompt", "?")))
                )
        else:
            g["no"] += 1
            odd.append(
                (
                    str(e.get("t_utc", "")),
                    pid,
                    texts.get(pid, ""),
                    str(e.get("answer")),
                    str(e.get("who", "?")),
                )
            )
    if not groups:
        return [Para("No operator prompts.")]
    unstated = split and any(g["given"][None] for g in groups.values())
    yes_heads = (
        tuple(name for _, name in _GIVEN_COLUMNS) + (("yes, how not stated",) if unstated else ())
        if split
        else ("yes",)
    )
    rows = tuple(
        (
            key,
            g["text"],
            str(g["asked"]),
            *(
                tuple(str(g["given"][k]) for k, _ in _GIVEN_COLUMNS)
                + ((str(g["given"][None]),) if unstated else ())
                if split
                else (str(g["yes"]),)
            ),
            str(g["no"]),
            str(g["asked"] - g["yes"] - g["no"]),
            ", ".join(sorted(g["who"])),
        )
        for key, g in groups.items()
    )
    out: list[Block] = [
        Table(("prompt", "question", "asked", *yes_heads, "no", "unanswered", "answered by"), rows)
    ]
    if split:
        out.append(Para(_GIVEN_NOTE))
    if carried:
        out += [
            Para(
                "Answers given with another prompt's answer (the lab's one key; not inspected on their own):"
            ),
            Table(("time (UTC)", "prompt", "question", "given with"), tuple(carried)),
        ]
    if odd:
        out += [
            Para("Answers other than yes:"),
            Table(("time (UTC)", "prompt", "question", "answer", "by"), tuple(odd)),
        ]
    return out


_GIVEN_NOTE = (
    "An inspection (a ring check) counts as made only when it was answered on its own prompt. "
    "'With another answer': the key that answered an earlier prompt (a shot's acceptance, or the ring "
    "check after the last hit) also answered this one, as the lab's console allows ([console] one_key); "
    "'by the script': a scripted run answered, and nobody was shown the question."
)


def _input_name(key: str) -> str:
    if key in _INPUTS:
        return _INPUTS[key]
    if m := re.fullmatch(r"t_(in|out)_g(\d+)", key):
        return f"{'inbound' if m[1] == 'in' else 'rebound'} crossing time, gate {m[2]} (s)"
    if m := re.fullmatch(r"x(\d+)", key):
        return f"gate {m[1]} position (m)"
    if m := re.fullmatch(r"delay_g(\d+)", key):
        return f"gate {m[1]} trigger delay (s)"
    return key


def _share(share: float) -> str:
    return f"{100 * share:.1f} %" if share >= 1e-3 else f"{100 * share:.1g} %"


def budget_blocks(record: dict[str, Any]) -> list[Block]:
    """The uncertainty budget of the bat's mean: every term's share of the result's u² (the
    measurement's inputs, the scatter, the ball's terms: rig.report.cert_shares), and the lab-time
    trade-off.

    The record keeps the budget of the metric's registry output (BBS's is e_A's: BBS is linear in
    e_A); it is scaled here by the registry's u_scale so that every u shown is in the metric's unit.
    """
    v = record.get("verdict") or {}
    budget = v.get("budget") or {}
    metric = v.get("metric")
    entry = registry.find(metric)
    scale = budget_scale(record)
    out_b = (budget.get("outputs") or {}).get((entry.budget_output if entry else metric) or "")
    if not out_b or scale is None:
        return []
    name, inputs = metric_label(metric), budget.get("inputs") or {}
    ball = v.get("ball") if isinstance(v.get("ball"), dict) else None
    split = result_terms(v, out_b, scale)
    if split is None:
        return []
    terms, total = split
    rows = [_term_row(t, inputs, total) for t in terms]
    sys_u = scale * out_b.get("systematic_variance", 0.0) ** 0.5
    rnd_u = scale * out_b.get("random_variance", 0.0) ** 0.5
    lead = f"{_term_name(terms[0])}, {_share(terms[0].variance / total)} of the result's u²" if terms else "—"
    note = ""
    if entry is not None and entry.u_scale is not None:
        by = f"{entry.u_scale_text} = {scale:.2f}{unit_suffix(metric)}"
        note = f" ({metric_label(entry.budget_output)}'s budget times {by})"
    u_model = scale * out_b.get("u", 0.0)
    out: list[Block] = [
        Heading("Uncertainty budget of the mean"),
        Para(
            f"Result: u = {_sig(v.get('u'), 3)}, U = {_sig(v.get('U'), 3)} (k = {v.get('coverage_k', 2):g}). "
            f"It combines the model budget of the measurement{note}, u = {_sig(u_model, 3)} "
            f"(systematic {_sig(sys_u)}, random {_sig(rnd_u)} for the mean of {budget.get('n_hits', '?')} "
            "hits), with the hits' observed scatter (docs/measurement.md, section 3)" + _ball_clause(v, ball)
        ),
        Para(
            f"Each term's share of the result's u² (u = {_sig(v.get('u'), 3)}), every term included; for a "
            "term that is not an input of the model budget, 'u of input' is its u in the result's unit:"
        ),
        Table(("input", "what", "u of input", "kind", f"share of u²({name})"), tuple(rows)),
        Para(f"Largest contribution: {lead}. Shared (systematic) inputs are not reduced by more hits."),
        *drag_blocks(v.get("drag")),
        *moi_blocks(record.get("moi")),
    ]
    return out + _tradeoff_blocks(record, v, name, scale, total - u_model**2)


def _term_name(t: Term) -> str:
    return _input_name(t.key) if t.measurement_input else (what(t.key) or t.key)


def _term_row(t: Term, inputs: dict[str, Any], total: float) -> tuple[str, str, str, str, str]:
    """A row of the budget table: an input of the measurement budget, or a term beside it."""
    if t.measurement_input:
        given = inputs.get(t.key) or {}
        kind = "systematic" if given.get("systematic") else "random"
        return (t.key, _input_name(t.key), _sig(given.get("u")), kind, _share(t.variance / total))
    kind = {SCATTER: "observed (random)", "others": "", "u_from_ball_cor": "lot's COR"}.get(t.key, "ball")
    return (
        t.key.removeprefix("u_"),
        what(t.key) or "",
        _sig(t.variance**0.5),
        kind,
        _share(t.variance / total),
    )


def _tradeoff_blocks(
    record: dict[str, Any], v: dict[str, Any], name: str, scale: float, other: float
) -> list[Block]:
    """The measurement's U against lab time for n valid hits, with the result's U beside it (the
    terms more hits do not reduce, `other` (variance), held as in this run)."""
    trade = v.get("tradeoff") or []
    if not trade:
        return []
    k = v.get("coverage_k", 2)
    n_proc = ((record.get("procedure") or {}).get("hits") or {}).get("valid_hits")
    rows_t = tuple(
        (
            str(r.get("hits")),
            str(r.get("shots")),
            _sig(scale * r.get("u", 0.0), 3),
            _sig(scale * r.get("expanded", 0.0), 3),
            _sig(k * (max(0.0, other) + (scale * r.get("u", 0.0)) ** 2) ** 0.5, 3),
            f"{r.get('lab_time_s', 0) / 60:.1f} min",
            "◀ this procedure" if r.get("hits") == n_proc else "",
        )
        for r in trade
    )
    return [
        Heading("Accuracy against lab time"),
        Para(
            f"The measurement part of the mean {name}'s U, from the model budget (without observed scatter), "
            f"for n valid hits; beside it the result's U (certified: {_sig(v.get('U'), 3)}, k = {k:g}) with "
            "the terms more hits do not reduce here (the scatter, the ball's and the lot's terms) as in "
            "this run:"
        ),
        Table(
            ("valid hits", "shots", "u (measurement)", "U (measurement)", "U (result)", "lab time", ""),
            rows_t,
        ),
    ]


def drag_blocks(drag: dict[str, Any] | None) -> list[Block]:
    """The drag correction to the impact point: its inputs (Cd, air) and what it changed."""
    if not drag:
        return [Para("No drag correction in this record (recorded before it existed): speeds as measured.")]
    air = drag.get("air") or {}
    if not drag.get("applied"):
        return [Heading("Drag correction", 3), Para("Not applied: the rig config states Cd = 0 (no drag).")]
    rows = (
        ("Cd, inbound", _num(drag.get("drag_coefficient"), 3), _sig(drag.get("drag_coefficient_u"))),
        (
            "Cd, rebound",
            _num(drag.get("rebound_drag_coefficient"), 3),
            _sig(drag.get("rebound_drag_coefficient_u")),
        ),
        ("air density (kg/m³)", _num(air.get("rho_kgm3"), 4), _sig(air.get("u_kgm3"))),
    )
    contrib = air.get("contributions") or {}
    return [
        Heading("Drag correction", 3),
        Para(
            "Gate speeds are corrected to the impact point for quadratic air drag "
            "(docs/measurement.md, 3.6). Air from the environment check: "
            f"{_num(air.get('temperature_c'), 1)} °C, {_num(air.get('humidity_pct'), 0)} % RH, "
            f"stated pressure {_num(air.get('pressure_kpa'), 2)} kPa; u of the density from pressure "
            f"{_sig(contrib.get('pressure'))}, temperature {_sig(contrib.get('temperature'))}, humidity "
            f"{_sig(contrib.get('humidity'))}, formula {_sig(contrib.get('formula'))} kg/m³. "
            f"The correction moved the mean {drag.get('output', '')} by {_num(drag.get('correction'), 5)} "
            f"(uncorrected {_num(drag.get('mean_uncorrected'), 5)}); Cd and the density are inputs of "
            "the budget above."
        ),
        Table(("input", "value", "standard u"), rows),
    ]


def moi_blocks(moi: dict[str, Any] | None) -> list[Block]:
    """The MOI's own budget: each input of the pendulum (or the entered value) and its share."""
    if not moi:
        return []
    rows = tuple(
        (
            str(c.get("input", "?")),
            str(c.get("what", "")),
            f"{_sig(c.get('value'), 6)} {c.get('unit', '')}",
            f"{_sig(c.get('u'))} {c.get('unit', '')}",
            _sig(c.get("u_moi_kgm2")),
            _share(float(c.get("share") or 0.0)),
        )
        for c in moi.get("contributions") or []
    )
    value, u = moi.get("moi_kgm2"), moi.get("u_kgm2")
    rel = 100 * u / value if isinstance(u, int | float) and isinstance(value, int | float) and value else None
    head = (
        f"MOI = {_num(value, 5)} kg m², u = {_sig(u)} kg m² ({_num(rel, 3)} %), "
        f"source: {moi.get('source', '?')}."
    )
    if not rows:
        return [
            Heading("MOI and its uncertainty", 3),
            Para(head + " Its inputs were not recorded (older run)."),
        ]
    formula = (
        " I = m g d T0²/(4π²), T0 = T/(1 + θ0²/16) (ASTM F2398 pendulum); the MOI enters the budget above "
        "as one systematic input shared by every hit."
    )
    return [
        Heading("MOI and its uncertainty", 3),
        Para(head + (formula if moi.get("source") == "pendulum" else "")),
        Table(("input", "what", "value", "u of input", "u of MOI (kg m²)", "share of u²(MOI)"), rows),
    ]
