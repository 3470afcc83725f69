"""A ball test's report: the lot, the test, its result with U, and every hit (JSON, Markdown, HTML).

The JSON document is the run's record (rig.report.record.run_record) with the lot's sections
added; Markdown and HTML render it. Every number comes from the run's own log.
"""

from __future__ import annotations

import html
from typing import Any

from rig.core import events as ev
from rig.core.ball import BALL_TESTS
from rig.report.record import run_record
from rig.store import Anchor, Store


def is_ball_test(store: Store, run_id: str) -> bool:
    """Whether the run is a ball test (its procedure is ccor or ball-cor)."""
    return store.run(run_id).procedure in BALL_TESTS


def lot_record(store: Store, run_id: str, anchor: Anchor | None = None) -> dict[str, Any]:
    """The ball test's record: the run's record, the lot, the test and the lot's result."""
    record = run_record(store, run_id, anchor)
    started = store.entries(run_id, kinds=[ev.RUN_STARTED])
    setup = started[0].payload if started else {}
    verdict = record.get("verdict") or {}
    result = verdict.get("lot_result")
    record["report"] = "ball-lot"
    record["test"] = setup.get("test")
    record["lot"] = setup.get("lot")
    record["lot_result"] = None if result is None else {**result, "run_id": run_id}
    record["meets_specification"] = verdict.get("meets_specification")
    return record


def _f(value: Any, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def _rows(record: dict[str, Any]) -> tuple[list[tuple[str, str]], list[list[str]], list[list[str]]]:
    """(summary rows, per-speed rows, per-hit rows) of the report."""
    lot, r = record.get("lot") or {}, record.get("lot_result")
    name = "CCOR" if record.get("test") == "ccor" else "COR"
    summary = [
        (
            "Lot",
            f"{lot.get('id', '-')} ({lot.get('maker', '-')} {lot.get('model', '-')}, "
            f"{lot.get('balls', '-')} balls)",
        ),
        ("Test", str(record.get("test"))),
        ("Procedure", str((record.get("procedure") or {}).get("name", "-"))),
        ("Edition", str((record.get("procedure") or {}).get("edition", "-"))),
        ("Target", str((record.get("procedure") or {}).get("target", "-"))),
        ("Run", record["run_id"]),
        ("Status", str(record.get("status"))),
    ]
    spec = {k: v for k, v in (lot.get("specification") or {}).items() if v is not None}
    cond = {k: v for k, v in (lot.get("conditioning") or {}).items() if v is not None}
    summary.append(("Specification", ", ".join(f"{k} {v}" for k, v in spec.items()) or "none entered"))
    summary.append(("Conditioning", ", ".join(f"{k} {v}" for k, v in cond.items()) or "not stated"))
    speeds: list[list[str]] = []
    hits: list[list[str]] = []
    if r is not None:
        summary += [
            (
                f"{name} (mean of the balls' means)",
                f"{_f(r['mean'])} +- {_f(r['U'])} (U, k = {r['coverage_k']:g}; u = {_f(r['u'], 5)})",
            ),
            ("Ball-to-ball SD", _f(r.get("sd_between_balls"))),
            (
                "Wear per hit",
                "-"
                if r.get("wear_per_hit") is None
                else f"{r['wear_per_hit']:+.5f} +- {r['wear_per_hit_u']:.5f} (u)",
            ),
            (
                "Balls x hits",
                f"{r['n_balls']} x {r['hits_per_ball']} ({r['n_hits']} valid hits, "
                f"mean hit count {r['mean_hit']:.2f})",
            ),
            ("Lab during the test", f"{_f(r.get('temp_c'), 1)} C, {_f(r.get('rh_pct'), 0)} % RH"),
            (
                "Meets its specification",
                {True: "yes", False: "NO", None: "no tolerance stated"}[record.get("meets_specification")],
            ),
        ]
        speeds = [
            [
                _f(p["target_speed_m_s"], 2),
                _f(p["speed_m_s"], 2),
                _f(p["mean"]),
                _f(p["u"], 5),
                _f(p.get("sd")),
                str(p["n"]),
            ]
            for p in r.get("per_speed", [])
        ]
        hits = [
            [
                str(p["shot"]),
                p["ball_id"],
                str(p["ball_hit"]),
                _f(p["target_speed_m_s"], 2),
                _f(p["speed_m_s"], 3),
                _f(p["cor"]),
                _f(p["u"], 5),
            ]
            for p in r.get("points", [])
        ]
    return summary, speeds, hits


SPEED_HEAD = ["target m/s", "measured m/s", "mean", "u of the mean (k = 1)", "SD of the hits", "hits"]
HIT_HEAD = ["shot", "ball", "ball's hit", "target m/s", "at impact m/s", "COR", "u of the COR (k = 1)"]


def render(record: dict[str, Any], fmt: str) -> str:
    """The report as Markdown ("md") or HTML ("html")."""
    summary, speeds, hits = _rows(record)
    title = f"Ball-lot report: {(record.get('lot') or {}).get('id', '?')} ({record.get('test')})"
    anchor = record.get("anchor") or {}
    foot = f"Record anchor {anchor.get('seq')}:{anchor.get('hash')} (rig verify --anchor checks it)."
    if fmt == "md":
        lines = [f"# {title}", "", "| | |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in summary]
        for head, body, caption in ((SPEED_HEAD, speeds, "Per speed"), (HIT_HEAD, hits, "Valid hits")):
            if body:
                lines += ["", f"## {caption}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
                lines += ["| " + " | ".join(row) + " |" for row in body]
        lines += ["", foot, ""]
        return "\n".join(lines)
    e = html.escape

    def table(head: list[str] | None, body: list[list[str]]) -> str:
        top = "" if head is None else "<tr>" + "".join(f"<th>{e(h)}</th>" for h in head) + "</tr>"
        return (
            "<table>"
            + top
            + "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>" for row in body)
            + "</table>"
        )

    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>{e(title)}</title>",
        "<style>body{font-family:sans-serif}td,th{border:1px solid #999;padding:2px 6px}"
        "table{border-collapse:collapse}</style>",
        f"</head><body><h1>{e(title)}</h1>",
        table(None, [[k, v] for k, v in summary]),
    ]
    if speeds:
        parts += ["<h2>Per speed</h2>", table(SPEED_HEAD, speeds)]
    if hits:
        parts += ["<h2>Valid hits</h2>", table(HIT_HEAD, hits)]
    parts += [f"<p>{e(foot)}</p></body></html>"]
    return "\n".join(parts) + "\n"
