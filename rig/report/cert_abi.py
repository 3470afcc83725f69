"""The accelerated break-in's section of a certificate: every stage and the verdict after break-in.

From the run record alone (its `abi` entries: compressions, rollings, stage results, inspections).
Each stage shows its barrel compression (start and end, and the drop from the new bat's), the
rolling done (depth x passes, by whom), the hoop frequency where measured, the BBCOR with its U,
and the model cross-check's prediction of that BBCOR from the stage's hoop frequency.
"""

from __future__ import annotations

from typing import Any

from rig.core import events as ev
from rig.report.cert_doc import Block, Heading, Para, Table

ABI_PLAN = ev.ABI_PLAN  # the plan's recorded name (rig.protocols.steps.plan_name)


def _num(x: Any, fmt: str) -> str:
    return "-" if not isinstance(x, int | float) or isinstance(x, bool) else format(x, fmt)


def _how(rolling: dict[str, Any]) -> str:
    """How a rolling was reported: by a person answering the prompt, or by a script."""
    return "script" if rolling.get("given") == ev.BY_SCRIPT else "prompt"


def stage_rows(entries: list[dict[str, Any]]) -> list[tuple[str, ...]]:
    """One row per measured stage, from the record's ABI entries in order."""
    forces = [e["force_lbf"] for e in entries if e["kind"] == ev.COMPRESSION_MEASURED]
    new = forces[0] if forces else None
    rows: list[tuple[str, ...]] = []
    for stage in sorted({e["stage"] for e in entries if e["kind"] in ev.ABI_KINDS}):
        own = [e for e in entries if e.get("stage") == stage]
        bc = [e["force_lbf"] for e in own if e["kind"] == ev.COMPRESSION_MEASURED]
        rolled = [e for e in own if e["kind"] == ev.BARREL_ROLLED]
        # a stage the break-in ended in before its BBCOR (too many steps, an interruption): its rolling
        result: dict[str, Any] = next((e for e in own if e["kind"] == ev.ABI_STAGE_MEASURED), {"result": {}})
        if "hoop_hz" not in result and rolled:
            result = {**result, "hoop_hz": rolled[-1].get("hoop_hz")}
        verdict, cc = result["result"], result["result"].get("cross_check") or {}
        drop = "-" if not bc or not new else f"{100 * (1 - bc[-1] / new):.1f}"
        rolling = "; ".join(
            f"{r['depth_in']:g} in x {r['passes']} ({r.get('who') or '?'}, {_how(r)})" for r in rolled
        )
        predicted = _num(cc.get("predicted"), ".4f")
        if cc.get("interval"):
            lo, hi = cc["interval"]
            predicted += f" [{lo:.4f}, {hi:.4f}]"
        elif cc.get("predicted") is not None:
            predicted += " (uncalibrated)"
        rows.append(
            (
                str(stage),
                " -> ".join(f"{f:.1f}" for f in (bc[0], bc[-1])) if bc else "-",
                drop,
                rolling or "none",
                _num(result.get("hoop_hz"), ".0f"),
                _num(verdict.get("mean"), ".4f"),
                _num(verdict.get("U"), ".4f"),
                predicted,
                str(verdict.get("verdict", "not measured")),
            )
        )
    return rows


def abi_blocks(record: dict[str, Any]) -> list[Block]:
    """The break-in section; [] for a run that is not one."""
    entries = record.get("abi")
    if not entries:
        return []
    verdict = record.get("verdict") or {}
    inspections = [e for e in entries if e["kind"] == ev.OPERATOR_ANSWERED]
    damaged = [e for e in inspections if not e.get("answer")]
    rollings = [e for e in entries if e["kind"] == ev.BARREL_ROLLED]
    scripted = sum(_how(e) == "script" for e in rollings)
    return [
        Heading("Accelerated break-in (NCAA, 2009)"),
        Para(
            "Barrel compression (BC: force at the tester's fixed displacement, lbf) at 6 in; BBCOR of the "
            "new bat; then stages of rolling until BC fell at least 5 % below the stage's start (none "
            "once more than 15 % below the new bat's), each followed by BBCOR and an inspection, until "
            "the bat exceeded the limit, showed damage or was broken in. How the 5 % and 15 % are "
            "counted is inferred, the passes per step assumed (protocols/abi.toml; docs/standards.md)."
        ),
        Table(
            (
                "stage",
                "BC start -> end (lbf)",
                "BC drop from new (%)",
                "rolling (depth x passes, who, reported at)",
                "hoop (Hz)",
                "BBCOR",
                "U",
                "predicted from hoop",
                "stage verdict",
            ),
            tuple(stage_rows(entries)),
        ),
        Para(
            f"Rolling reports: {len(rollings) - scripted} answered at the prompt by a person, {scripted} "
            "given by a script (the rolling the plan asked for, taken as done: a simulated or scripted "
            "run; a simulated run's hoop frequency is its simulated barrel's tap)."
        ),
        Para(
            f"Inspections: {len(inspections)}, damage reported in "
            + (", ".join(e["prompt_id"].removeprefix(ev.ABI_DAMAGE_PROMPT) for e in damaged) or "none")
            + "."
        ),
        Para(f"Verdict after break-in: {verdict.get('verdict', 'none yet')}. {verdict.get('reason') or ''}"),
    ]
