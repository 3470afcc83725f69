"""A run's certificate, the document a lab's quality manager signs, as Markdown or standalone HTML.

Built from the run record alone (`rig.report.record.run_record`): every shot appears, valid or not.
Rendering writes no file unless `figures_dir` is given. Markdown has figures only then: PNG files
written there, linked relative to the folder of `output` (the path the document will be saved
to), or by absolute path when `output` is not given (the text may then go anywhere); without
`figures_dir` it draws nothing, so it is quick (no matplotlib, no model solves). HTML always
embeds its figures as SVG data: URIs drawn in memory (vector: they scale for print), so it stands
alone; `figures_dir` also saves them there as PNG. Nothing in the document depends on the time of
rendering: the same record gives the same text.
"""

from __future__ import annotations

import math
import shlex
from dataclasses import replace
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from rig.core import events as ev
from rig.core.bat import PIVOT_FROM_KNOB_IN
from rig.core.errors import ConfigError
from rig.core.events import Verdict
from rig.core.units import INCH, OUNCE
from rig.report.cert_abi import ABI_PLAN, abi_blocks
from rig.report.cert_ball import ball_blocks
from rig.report.cert_bpf import basis_rows, bpf_blocks
from rig.report.cert_crosscheck import cross_check_blocks
from rig.report.cert_doc import Banner, Block, Code, Figure, Heading, Para, Table, kv, to_html, to_markdown
from rig.report.cert_instruments import instrument_blocks
from rig.report.cert_plots import certification_hits, metric_label, svg_figures, unit_suffix, write_figures
from rig.report.cert_quality import quality_blocks
from rig.report.cert_report import (
    STATEMENT,
    authorisation_blocks,
    deviation_blocks,
    identification_blocks,
    letterhead_blocks,
    mark,
    page_marks,
    report_id,
    seal_blocks,
)
from rig.report.cert_retest import retest_blocks
from rig.report.cert_sections import budget_blocks, operator_blocks, shot_blocks

FORMATS = ("md", "html")
NOT_CERTIFIED = "NOT CERTIFIED — run interrupted"
NOT_CERTIFIED_ENDED = "NOT CERTIFIED — run ended without a verdict"
NOT_CERTIFIED_RUNNING = "NOT CERTIFIED — run in progress"


def render(
    record: dict[str, Any],
    fmt: str,
    figures_dir: str | Path | None = None,
    *,
    output: str | Path | None = None,
) -> str:
    """The certificate as 'md' or 'html' text; writes its figures (PNG) into figures_dir if given.

    `output`, the path the text will be saved to, makes the Markdown's image links relative to it.
    """
    if fmt not in FORMATS:
        raise ConfigError(
            f"unknown certificate format {fmt!r}: use one of {', '.join(FORMATS)}", source="--format"
        )
    pngs = write_figures(record, Path(figures_dir)) if figures_dir is not None else {}
    if fmt == "md":
        base = Path(output).parent if output is not None else None
        return to_markdown(build(record, {k: Figure(p, c) for k, (p, c) in pngs.items()}), base)
    svgs = svg_figures(record)
    figures = {k: Figure(pngs[k][0] if k in pngs else None, c, svg=svg) for k, (svg, c) in svgs.items()}
    return to_html(build(record, figures), title(record), page_marks(record))


def title(record: dict[str, Any]) -> str:
    """'Bat performance certificate: <procedure name> — bat <id>' (the report's title)."""
    proc, bat = record.get("procedure") or {}, record.get("bat") or {}
    return f"Bat performance certificate: {proc.get('name', 'unknown procedure')} — bat {bat.get('id', '?')}"


def own_plan(record: dict[str, Any]) -> list[tuple[str, str]]:
    """The plan row, for a run carried out by a lab's own plan rather than the standard steps."""
    plan = record.get("plan")
    if not plan:
        return []
    if plan == ABI_PLAN:
        return [("plan", f"{plan}: the NCAA accelerated break-in, stage by stage (below)")]
    return [("plan", f"{plan}: a lab's own plan, not the standard procedure's steps (rig.plans)")]


def build(record: dict[str, Any], fig: dict[str, Figure]) -> list[Block]:
    """Every section of the certificate, in reading order; `fig`: the figures drawn, by key.

    First the report (ISO/IEC 17025 7.8.2.1: rig.report.cert_report), then the technical annex with
    everything the record holds, then a clear end."""
    proc = record.get("procedure") or {}
    marked = mark(record)
    blocks: list[Block] = [
        *letterhead_blocks(record),
        Heading(title(record), 1),
        Para(f"Test report {report_id(record)}" + (f" — {marked}" if marked else ""), strong=True),
        *[replace(b, mark=marked) for b in verdict_blocks(record) if isinstance(b, Banner)],
        Para(STATEMENT),
        Heading("Report"),
        *identification_blocks(record),
        Heading("Deviations"),
        *deviation_blocks(record),
        *quality_blocks(record),
        Heading("Seal of the record"),
        *seal_blocks(record),
        Heading("Authorisation"),
        *authorisation_blocks(record),
        Heading("Technical annex", 1, new_page=True),
        Para(f"Edition: {proc.get('edition', 'not recorded')}"),
        kv(
            [
                ("run", str(record.get("run_id"))),
                ("procedure", f"{proc.get('name', '?')} (standard: {proc.get('standard', '?')})"),
                *_dated(proc),
                *basis_rows(record),
                *own_plan(record),
                ("started (UTC)", str(record.get("started_utc") or "?")),
                ("record status", str(record.get("status"))),
            ]
        ),
        *verdict_detail_blocks(record),
        *bpf_blocks(record),
        *abi_blocks(record),
        *retest_blocks(record),
        Heading("Bat"),
        bat_table(record),
        Heading("Rig and software"),
        rig_table(record),
        Heading("Instruments"),
        *instrument_blocks(record),
        Heading("Lab environment"),
        *environment_blocks(record),
        *shot_blocks(record, _decimals(record), fig),
        Heading("Operator prompts and answers"),
        *operator_blocks(record),
        Heading("Interruptions and resumes"),
        *interruption_blocks(record),
        *budget_blocks(record),
        *ball_blocks(record, _decimals(record)),
        Heading("Model cross-check"),
        *cross_check_blocks(record, fig),
        Heading("Record anchor"),
        *anchor_blocks(record),
        Para(f"End of report {report_id(record)}.", strong=True),
    ]
    return blocks


def _dated(proc: dict[str, Any]) -> list[tuple[str, str]]:
    """The edition's date and the ball's class where the procedure states them (older ones do not)."""
    ball = proc.get("ball") or {}
    rows = [("edition in force from", proc.get("edition_date")), ("ball class", ball.get("ball_class"))]
    return [(k, str(v)) for k, v in rows if v]


def _decimals(record: dict[str, Any]) -> int:
    """Decimal places of the result: U to two significant digits, the mean to match (GUM 7.2.6)."""
    big_u = (record.get("verdict") or {}).get("U")
    if not isinstance(big_u, int | float) or big_u <= 0 or not math.isfinite(big_u):
        return 4
    return max(0, min(8, 1 - math.floor(math.log10(big_u))))


def fmt_num(x: Any, decimals: int) -> str:
    """A number to fixed decimals, or '—' when absent."""
    return "—" if not isinstance(x, int | float) else f"{x:.{decimals}f}"


def decision_words(record: dict[str, Any]) -> str:
    """The decision rule as a sentence."""
    v, proc = record.get("verdict") or {}, record.get("procedure") or {}
    name, limit = metric_label(v.get("metric") or proc.get("standard")), v.get("limit", proc.get("limit"))
    k = v.get("coverage_k", (proc.get("decision") or {}).get("coverage_k", 2.0))
    rule = (proc.get("decision") or {}).get("rule") or (
        "guarded" if "guarded" in str(v.get("decision_rule")) else ""
    )
    if rule == "guarded":
        return (
            f"Guarded acceptance (k = {k:g}): the bat passes only if its mean {name} plus the expanded "
            f"uncertainty U = {k:g} u is at or below the limit {limit}; a mean below the limit but closer "
            "to it than U fails (guard band)."
        )
    return (
        f"Simple acceptance: the bat passes if its mean {name} is at or below the limit {limit}; "
        "U is reported but does not enter the decision."
    )


def resume_command(record: dict[str, Any]) -> str:
    """How to resume the run: on the same simulated scene, or with the lab's rig file."""
    scene: str | None = None
    for url in ((record.get("rig") or {}).get("ports") or {}).values():
        if isinstance(url, str) and url.startswith("sim://"):
            scenes = parse_qs(urlsplit(url).query).get("scene")
            scene = scenes[0] if scenes else None
            break
    where = f"--sim {shlex.quote(scene)}" if scene else "--config RIG.toml"
    return f"rig certify --resume {record.get('run_id')} {where}"


def _budget_way_out(record: dict[str, Any], stop: dict[str, Any]) -> list[Block]:
    """After the re-shoot budget: resume with the rig check recorded, or end the run (recorded)."""
    if not stop.get("budget_exceeded"):
        return []
    return [
        Para("The re-shoot budget is spent: once the rig is checked, resume with the check recorded:"),
        Code(f"{resume_command(record)} --rig-checked --who NAME --why TEXT"),
        Para("or end the run with no verdict (recorded):"),
        Code(f"rig certify --end {record.get('run_id')} --who NAME --why TEXT"),
    ]


def verdict_blocks(record: dict[str, Any]) -> list[Block]:
    """The verdict banner and its figures, or NOT CERTIFIED: ended, in progress, or interrupted with
    the resume command (the run's status as every output shows it)."""
    v = record.get("verdict")
    ended = record.get("ended")
    if not v and ended:
        return [
            Banner(
                NOT_CERTIFIED_ENDED,
                (
                    f"Run ended without a verdict by {ended.get('who', '?')} ({ended.get('t_utc', '')}): "
                    f"{ended.get('why', '')}",
                    "No verdict: this record certifies nothing.",
                ),
                "none",
            )
        ]
    if not v and record.get("status") == "running":  # a runner holds it now: no verdict yet
        return [Banner(NOT_CERTIFIED_RUNNING, ("No verdict yet: this record certifies nothing.",), "none")]
    if not v:
        stops = [i for i in record.get("interruptions", []) if i.get("kind") == ev.RUN_INTERRUPTED]
        reason = stops[-1].get("reason", "") if stops else "the run stopped before a verdict was recorded"
        return [
            Banner(
                NOT_CERTIFIED, (f"Reason: {reason}", "No verdict: this record certifies nothing."), "none"
            ),
            Para(
                "Fix the cause, then resume the run (add --db FILE if the record is not in rig-records.db):"
            ),
            Code(resume_command(record)),
            *_budget_way_out(record, stops[-1] if stops else {}),
        ]
    tone = "pass" if v.get("verdict") == Verdict.PASS else "fail"
    name, limit = metric_label(v.get("metric")), v.get("limit")
    if v.get("mean") is None:
        return [
            Banner(f"{v.get('verdict')} — {v.get('reason', 'no metric measured')}", (f"limit {limit}",), tone)
        ]
    d = _decimals(record)
    unit = unit_suffix(v.get("metric"))
    mean, big_u = v["mean"], v.get("U") or 0.0
    loc, q = v.get("location_in"), v.get("impact_from_pivot_m")
    lines = (
        f"{name} = {fmt_num(mean, d)} ± {fmt_num(big_u, d)}{unit} (k = {v.get('coverage_k', 2):g}) "
        f"against the limit {limit}{unit}; zone: {v.get('zone', '?')}",
        decision_words(record),
    )
    return [
        Banner(f"{v.get('verdict')}: {name} {fmt_num(mean, d)}{unit}", lines, tone),
        kv(
            [
                ("metric", f"{name}: {v.get('definition', '')}"),
                (
                    "mean of the valid hits corrected for their balls"
                    if any((v.get("ball") or {}).get("corrections") or [])
                    else "mean of valid hits",
                    f"{fmt_num(mean, d)}{unit} (n = {v.get('n_hits')})",
                ),
                ("standard uncertainty u", f"{fmt_num(v.get('u'), d + 1)}{unit}"),
                (f"expanded uncertainty U (k = {v.get('coverage_k', 2):g})", f"{fmt_num(big_u, d)}{unit}"),
                ("mean + U", f"{fmt_num(mean + big_u, d)}{unit}"),
                ("limit", f"{limit}{unit}"),
                ("margin: limit − (mean + U)", f"{fmt_num((limit or 0.0) - mean - big_u, d)}{unit}"),
                ("decision rule", decision_words(record)),
                ("basis of the limit", str((record.get("procedure") or {}).get("limit_note", "—"))),
                ("impact point", f"{loc} in from the barrel end (Q = {fmt_num(q, 4)} m from the pivot)"),
                ("hits averaged", ", ".join(str(s["index"]) for s in certification_hits(record)) or "—"),
            ]
        ),
    ]


def verdict_detail_blocks(record: dict[str, Any]) -> list[Block]:
    """The verdict's figures, the resume commands of a run without one: the annex's Verdict section."""
    rest = [b for b in verdict_blocks(record) if not isinstance(b, Banner)]
    return [Heading("Verdict"), *rest] if rest else []


def bat_table(record: dict[str, Any]) -> Table:
    """Identity and properties of the bat, and how its MOI was obtained."""
    bat, moi = record.get("bat") or {}, record.get("moi")
    length, weight = bat.get("length_in"), bat.get("weight_oz")
    drop = f"{weight - length:+g}" if length is not None and weight is not None else "—"
    hoop = bat.get("hoop_hz")
    if moi:
        value, u = moi.get("moi_kgm2"), moi.get("u_kgm2")
        how = f"measured on the rig ({moi.get('source', '?')}"
        if moi.get("source") == "entered":
            how = "entered from the bat file, with the standard uncertainty it states ("
        if moi.get("period_s") is not None:
            cycles, amp = moi.get("cycles"), moi.get("amplitude_deg")
            how += f": period {moi['period_s']:.5f} s over {cycles} cycles at {amp}° amplitude"
        how += ")"
    elif bat.get("moi_kgm2") is not None:
        value, u = bat["moi_kgm2"], bat.get("moi_u_kgm2")
        how = "from the bat file, with the standard uncertainty it states"
    else:
        value, u, how = None, None, "not measured (the run stopped before the MOI)"
    moi_text = "—" if value is None else f"{value:.5f} kg m²"
    if value is not None and u:
        moi_text += f" ± {u:.2g} (standard uncertainty, {100 * u / value:.2f} %)"
    return kv(
        [
            ("bat id", str(bat.get("id", "?"))),
            ("length", "—" if length is None else f"{length:g} in ({length * INCH:.3f} m)"),
            ("weight", "—" if weight is None else f"{weight:g} oz ({weight * OUNCE:.3f} kg)"),
            ("drop (weight − length)", drop),
            ("barrel", str(bat.get("barrel", "—"))),
            ("hoop frequency", "not given" if hoop is None else f"{hoop:g} Hz (bat file)"),
            (
                "balance point",
                "—" if bat.get("balance_point_in") is None else f"{bat['balance_point_in']:g} in",
            ),
            (f"MOI about the pivot ({PIVOT_FROM_KNOB_IN:g} in from the knob)", moi_text),
            ("MOI obtained", how),
        ]
    )


def rig_table(record: dict[str, Any]) -> Table:
    """The rig's set-up and the software that ran it."""
    rig, sw = record.get("rig") or {}, record.get("software") or {}
    gates = rig.get("gates") or {}
    pos = " / ".join(f"{x:.3f}" for x in gates.get("positions_m") or []) or "—"
    u_pos = gates.get("position_uncertainty_m")
    ports = {k: v for k, v in (rig.get("ports") or {}).items() if v}
    ports |= {k: d["address"] for k, d in (rig.get("devices") or {}).items() if d and d.get("address")}
    aim = (rig.get("aim") or {}).get("speed_m_s") or []
    return kv(
        [
            ("rig", str(rig.get("name", "—"))),
            *[(f"{dev} port", str(url)) for dev, url in sorted(ports.items())],
            (
                "gate positions from the impact point",
                f"{pos} m" + (f" (± {u_pos * 1000:.3f} mm)" if u_pos else ""),
            ),
            ("cannon cycle", f"{rig['cannon_cycle_s']:g} s" if rig.get("cannon_cycle_s") else "—"),
            ("aim calibration", f"{len(aim)} points, {min(aim):.1f}–{max(aim):.1f} m/s" if aim else "—"),
            *[(f"software: {name}", str(version)) for name, version in sorted(sw.items())],
        ]
    )


def environment_blocks(record: dict[str, Any]) -> list[Block]:
    """Temperature and humidity checks against the procedure's ranges."""
    env = (record.get("procedure") or {}).get("environment") or {}
    t, h = env.get("temperature_c") or [None, None], env.get("humidity_pct") or [None, None]
    checks = record.get("environment") or []
    rows = tuple(
        (
            str(c.get("t_utc", "")),
            fmt_num(c.get("temperature_c"), 1),
            fmt_num(c.get("humidity_pct"), 0),
            "yes" if c.get("ok") else "NO",
        )
        for c in checks
    )
    return [
        Para(f"Allowed: {t[0]}–{t[1]} °C, {h[0]}–{h[1]} % RH."),
        Table(("checked (UTC)", "temperature (°C)", "humidity (% RH)", "within range"), rows)
        if rows
        else Para("No environment check recorded."),
    ]


_STOP_WORDS = {
    ev.RUN_INTERRUPTED: "interrupted",
    ev.RUN_RESUMED: "resumed",
    ev.RIG_CHECKED: "rig checked",
    ev.RUN_ENDED: "ended, no verdict",
}


def _stop_detail(i: dict[str, Any]) -> str:
    if i.get("kind") == ev.RIG_CHECKED:
        return (
            f"by {i.get('who', '?')}: {i.get('why', '')} (re-shoot budget starts again after "
            f"{i.get('invalid_shots_before', '?')} invalid shots)"
        )
    if i.get("kind") == ev.RUN_ENDED:
        return f"by {i.get('who', '?')}: {i.get('why', '')}"
    if "reason" in i:
        return str(i["reason"])
    return f"{i.get('shots_so_far', '?')} shots recorded before"


def interruption_blocks(record: dict[str, Any]) -> list[Block]:
    """Every interruption and resume, in order."""
    rows = tuple(
        (_STOP_WORDS.get(str(i.get("kind")), str(i.get("kind"))), str(i.get("t_utc", "")), _stop_detail(i))
        for i in record.get("interruptions") or []
    )
    return [
        Table(("event", "time (UTC)", "detail"), rows)
        if rows
        else Para("None: the run went straight through.")
    ]


def anchor_blocks(record: dict[str, Any]) -> list[Block]:
    """The record's head: check the store against it with rig verify."""
    a = record.get("anchor") or {}
    seq, digest = a.get("seq", 0), a.get("hash", "")
    return [
        Para(
            f"Rendered from this run's {record.get('entries', '?')} entries in the hash-chained record; "
            f"its last is entry {seq}, hash {digest}. To check that the record has not been altered "
            "since this certificate was issued (add --db FILE to name the store):"
        ),
        Code(f"rig verify --anchor {seq}:{digest}"),
        *([Para(record["coverage"]["text"])] if record.get("coverage") else []),
    ]
