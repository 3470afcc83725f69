"""The report's first page, as ISO/IEC 17025 7.8.2.1 lists its content: the lab, the report's id and
issue, the customer, the item, the dates, the method, who tested, the statement, the deviations,
the seal and who authorises it. From the record alone (rig.report.record, rig.report.issue).

A run recorded before the lab, the operator and the seal were recorded says so where they would be.
"""

from __future__ import annotations

from typing import Any

from rig.core import events as ev
from rig.core.config import recorded_rig_simulated
from rig.report.cert_doc import Block, Code, Logo, PageMarks, Para, Table, kv
from rig.report.issue import DRAFT_MARK, SIMULATED_MARK, default_report_id

STATEMENT = (
    "The results relate only to the item tested, as received. This report shall not be reproduced "
    "except in full without the written approval of the laboratory."
)
BEFORE = "not recorded (this run was recorded before its report recorded it)"


def simulated(record: dict[str, Any]) -> bool:
    """Whether the run was made on a simulated rig: as its creation recorded it, else (an older run)
    by the rig its RunStarted recorded (a sim:// address, or a device marked simulated)."""
    if "simulated" in record:
        return bool(record["simulated"])
    rig = record.get("rig")
    return isinstance(rig, dict) and recorded_rig_simulated(rig)


def mark(record: dict[str, Any]) -> str:
    """SIMULATED - NOT A CERTIFICATION for a simulated run, else ''."""
    return SIMULATED_MARK if simulated(record) else ""


def report_id(record: dict[str, Any]) -> str:
    """The report's id: as issued, else the one it will be issued with."""
    issued = record.get("issue") or {}
    return str(issued.get("report_id") or record.get("report_id") or default_report_id(str(record["run_id"])))


def page_marks(record: dict[str, Any]) -> PageMarks:
    """What every printed page carries: the report id, the lab, a simulated run's mark, a draft's."""
    lab = record.get("lab") or {}
    return PageMarks(
        report_id(record),
        str(lab.get("name") or ""),
        mark(record),
        "" if record.get("issue") else DRAFT_MARK,
    )


def letterhead_blocks(record: dict[str, Any]) -> list[Block]:
    """The lab's logo (HTML), name, address and accreditation, as recorded when the run was created."""
    lab = record.get("lab")
    if not lab:
        return []
    logo = lab.get("logo") or {}
    out: list[Block] = []
    if logo.get("data_b64"):
        out.append(Logo(str(logo.get("media_type")), str(logo["data_b64"]), f"logo of {lab.get('name')}"))
    accredited = lab.get("accreditation_id")
    out.append(
        Para(
            f"{lab.get('name')} — {' / '.join(str(lab.get('address', '')).splitlines())}"
            + (f" — accreditation {accredited}" if accredited else ""),
            strong=True,
        )
    )
    return out


def _lab_text(record: dict[str, Any]) -> str:
    if "lab" not in record:
        return BEFORE
    lab = record["lab"]
    if not lab:
        return "not named: no lab identity file was given for this run (--lab, RIG_LAB or the rig config)"
    address = ", ".join(str(lab.get("address", "")).splitlines())
    accredited = lab.get("accreditation_id")
    return f"{lab.get('name')}, {address}" + (
        f"; accreditation {accredited}" if accredited else "; no accreditation stated"
    )


def _dates(record: dict[str, Any]) -> str:
    """The test's dates (UTC): from the run's start to its last recorded step."""
    times = [str(record.get("started_utc") or "")]
    for key in ("interruptions", "environment", "operator"):
        times += [str(x.get("t_utc") or "") for x in record.get(key) or []]
    times += [str(s.get("requested_utc") or "") for s in record.get("shots") or []]
    days = sorted({t[:10] for t in times if len(t) >= 10})
    if not days:
        return "not recorded"
    return days[0] if len(days) == 1 else f"{days[0]} to {days[-1]}"


def _g(x: Any) -> str:
    return f"{x:g}" if isinstance(x, int | float) else "?"


def _item(record: dict[str, Any]) -> str:
    bat = record.get("bat") or {}
    ident = [f"{k} {bat[k]}" for k in ("maker", "model", "serial") if bat.get(k)]
    size = f"{bat.get('barrel', '?')} barrel, {_g(bat.get('length_in'))} in, {_g(bat.get('weight_oz'))} oz"
    who = ", ".join(ident) if ident else "maker, model and serial not given in the bat file"
    return f"bat {bat.get('id', '?')}: {who}; {size}"


def tested_by_text(record: dict[str, Any]) -> str:
    """Who performed the test: the operator named when the run was created, and who answered its prompts."""
    if "tested_by" not in record:
        return BEFORE
    t = record.get("tested_by") or {}
    name, answered = t.get("name"), t.get("answered_by")
    if name:
        return str(name) + (f" (prompts answered by {answered})" if answered and answered != name else "")
    return f"no operator named (a scripted run: prompts answered by {answered or '?'})"


def _issue_text(record: dict[str, Any]) -> str:
    issued = record.get("issue")
    if not issued:
        return DRAFT_MARK
    return f"{issued.get('issued')}, authorised by {issued.get('by')}"


def identification_blocks(record: dict[str, Any]) -> list[Block]:
    """The report's identification: id, issue, lab, customer, item, dates, method, who tested."""
    bat, proc = record.get("bat") or {}, record.get("procedure") or {}
    edition = proc.get("edition", "edition not recorded")
    method = f"{proc.get('name', '?')} (standard: {proc.get('standard', '?')}); {edition}"
    if record.get("plan"):
        method += f"; run by the lab's own plan {record['plan']}"
    rig = (record.get("rig") or {}).get("name", "?")
    return [
        kv(
            [
                ("report id", report_id(record)),
                ("date of issue", _issue_text(record)),
                ("laboratory", _lab_text(record)),
                ("customer", str(bat.get("customer") or "not recorded (no customer in the bat file)")),
                ("item tested", _item(record)),
                ("condition on receipt", str(bat.get("condition") or "not recorded")),
                ("date of receipt", str(bat.get("received") or "not recorded")),
                ("date of test (UTC)", _dates(record)),
                ("method", method),
                ("rig", f"{rig}" + (" (simulated: no bat was measured)" if simulated(record) else "")),
                ("test performed by", tested_by_text(record)),
                ("run (record)", str(record.get("run_id"))),
            ]
        )
    ]


def _overrides(record: dict[str, Any]) -> list[tuple[str, str, str]]:
    rows = []
    for session in record.get("instruments") or []:
        override = session.get("override")
        if override:
            overdue = ", ".join(
                str(e.get("name", "?"))
                for e in session.get("equipment") or []
                if e.get("status") == "past due"
            )
            rows.append(
                (
                    f"calibration past due ({overdue or '?'}) accepted by override",
                    str(session.get("t_utc") or ""),
                    f"by {override.get('who', '?')}: {override.get('why', '?')}",
                )
            )
    return rows


_STOPS = {
    ev.RUN_INTERRUPTED: "run interrupted",
    ev.RUN_RESUMED: "run resumed",
    ev.RIG_CHECKED: "rig checked, re-shoot budget restarted",
    ev.RUN_ENDED: "run ended without a verdict on the operator's word",
    "RunLockBroken": "a stopped runner's lock broken",
}


def deviation_rows(record: dict[str, Any]) -> list[tuple[str, str, str]]:
    """Every departure from a straight run the record holds: (what, time (UTC), detail)."""
    rows = _overrides(record)
    if record.get("plan"):
        rows.append(("a lab's own plan ran the procedure, not its standard steps", "", str(record["plan"])))
    for i in record.get("interruptions") or []:
        kind = str(i.get("kind"))
        who = f"by {i['who']}: {i.get('why', '')}" if i.get("who") else ""
        detail = who or str(i.get("reason") or f"{i.get('shots_so_far', '?')} shots recorded before")
        rows.append((_STOPS.get(kind, kind), str(i.get("t_utc") or ""), detail))
    for s in record.get("shots") or []:
        for r in s.get("reasons") or []:
            if r.get("code") == "OPERATOR_REJECTED":
                rows.append(
                    (f"shot {s.get('index')} rejected by the operator on review", "", str(r.get("message")))
                )
    loc = record.get("location") or {}
    if loc.get("bracketed") is False:
        rows.append(
            (
                "location of maximum performance not bracketed; certified there",
                "",
                f"on the word of {loc.get('accepted_by', '?')}",
            )
        )
    for c in record.get("environment") or []:
        if not c.get("ok"):
            rows.append(
                (
                    "lab environment outside the procedure's range",
                    str(c.get("t_utc") or ""),
                    f"{c.get('temperature_c')} °C, {c.get('humidity_pct')} % RH",
                )
            )
    for e in record.get("operator") or []:
        if e.get("kind") == ev.OPERATOR_ANSWERED and e.get("answer") is not True:
            rows.append(
                (
                    f"prompt {e.get('prompt_id')} answered {e.get('answer')}",
                    str(e.get("t_utc") or ""),
                    str(e.get("who")),
                )
            )
    return _unnamed(record) + rows + _unasked(record)


def _unnamed(record: dict[str, Any]) -> list[tuple[str, str, str]]:
    """A run on a real rig whose operator gave no name: who performed the test is not on record."""
    named = (record.get("tested_by") or {}).get("name")
    if "tested_by" not in record or named or simulated(record):
        return []
    return [
        (
            "no operator named when the run started: who performed the test is not on record",
            str(record.get("started_utc") or ""),
            "rig certify --operator NAME, or the console's operator field, names them",
        )
    ]


_UNASKED = {  # how a ring check was passed without being inspected on its own prompt (protocols.control)
    "with": "ring checks passed with another prompt's answer (the lab's one key), not on their own prompt",
    "script": "ring checks answered by the script: nobody was shown them",
}


def _unasked(record: dict[str, Any]) -> list[tuple[str, str, str]]:
    """One row per way ring checks were passed without their own inspection, naming them."""
    found: dict[str, list[dict[str, Any]]] = {}
    for e in record.get("operator") or []:
        if (
            e.get("kind") == ev.OPERATOR_ANSWERED
            and e.get("answer") is True
            and str(e.get("prompt_id", "")).startswith("ring-")
            and e.get("given") in _UNASKED
        ):
            found.setdefault(str(e["given"]), []).append(e)
    rows = []
    for given, answers in found.items():
        named = ", ".join(
            str(a.get("prompt_id")) + (f" (with {a.get('with_prompt')})" if given == "with" else "")
            for a in answers
        )
        rows.append((f"{len(answers)} {_UNASKED[given]}", str(answers[0].get("t_utc") or ""), named))
    return rows


def deviation_blocks(record: dict[str, Any]) -> list[Block]:
    """The deviations, or a line saying there were none."""
    rows = deviation_rows(record)
    if not rows:
        return [
            Para(
                "None recorded: no override, interruption, rig check or operator decision departed "
                "from the procedure."
            )
        ]
    return [Table(("deviation", "time (UTC)", "recorded detail"), tuple(rows))]


def seal_blocks(record: dict[str, Any]) -> list[Block]:
    """Whether the record is signed, by which rig's key, its fingerprint, and how to check it."""
    run_id, seal = record.get("run_id"), record.get("seal")
    a = record.get("anchor") or {}
    check: list[Block] = [
        Para("Check the record against this report (add --db FILE to name the store):"),
        Code(f"rig verify --run {run_id}\nrig verify --anchor {a.get('seq', 0)}:{a.get('hash', '')}"),
    ]
    if seal is None:
        return [Para(f"{BEFORE.capitalize()}: rig verify says whether the run is signed."), *check]
    if not seal.get("signed"):
        text = (
            f"Not signed: the record of rig {seal.get('rig') or '?'} is hash-chained"
            + (" and sealed" if seal.get("sealed") else "")
            + " but carries no rig signature (rig keys: docs/records.md)."
        )
        return [Para(text), *check]
    rig, fp = seal.get("rig"), seal.get("fingerprint")
    state = seal.get("check")
    if state == "valid":
        said = f"Signed with rig {rig}'s Ed25519 key, fingerprint {fp}; the signature holds in this store."
    elif state == "key not listed in this store":
        said = (
            f"Signed with rig {rig}'s key {fp}, which this store does not list: "
            "rig verify cannot check it yet."
        )
    else:
        said = f"SIGNATURE DOES NOT HOLD (rig {rig}, key {fp}): {state}."
    pin = Code(f"rig verify --run {run_id} --trusted-key {rig}:{fp}")
    return [
        Para(said),
        *check,
        Para(
            "With the rig's fingerprint kept outside the store, check that no other key was put in its place:"
        ),
        pin,
    ]


def authorisation_blocks(record: dict[str, Any]) -> list[Block]:
    """Who performed the test and who authorised the report (its issue), with room to sign."""
    issued = record.get("issue") or {}
    t = record.get("tested_by") or {}
    tester = str(t.get("name") or "") if "tested_by" in record else ""
    return [
        Table(
            ("role", "name", "date", "signature"),
            (
                ("test performed by", tester or tested_by_text(record), _dates(record), ""),
                (
                    "authorised by",
                    str(issued.get("by") or DRAFT_MARK),
                    str(issued.get("issued") or ""),
                    "",
                ),
            ),
        )
    ]
