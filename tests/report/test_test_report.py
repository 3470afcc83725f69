"""The test report an accreditation body accepts (issue 24 item 4): ISO/IEC 17025 7.8.2.1's items, each
present in the HTML and the Markdown and each taken from the record; the simulated mark; the seal; the
lab identity file refused in one line when it is hostile; old bat files and registrations unchanged.

The expected values come from what the test wrote (lab file, bat file, names) and from the store's
own entries read here, not from the report code.
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import math
import os
import re
import statistics
import struct
import zlib
from pathlib import Path
from typing import Any
from unittest import mock

import pytest

from rig.store import Store
from tests.unit.clirun import QUICK_PROCEDURE, run_cli

LAB_NAME = "Acme Bat Testing Lab"
ADDRESS = ("12 Diamond Road", "Springfield 01101")
ACCREDITATION = "A2LA 4321.01"
CUSTOMER = "Northside Bats Inc."
MAKER, MODEL, SERIAL = "Slugger Co", "Thunder 33", "SN-0042"
CONDITION = "new, no visible damage"
RECEIVED = "2026-11-02"
OPERATOR, CHECKER, AUTHORISER = "A. Technician", "B. Checker", "Q. Manager"
WILD = '[[effects]]\nkind = "speed_scatter"\nsigma_rel = 0.05\n'  # stops a run by its re-shoot budget
BAT = f"""\
[bat]
id = "RPT-1"
length_in = 33.0
weight_oz = 30.0
barrel = "aluminium"
hoop_hz = 3600.0
balance_point_in = 22.0
customer = "{CUSTOMER}"
maker = "{MAKER}"
model = "{MODEL}"
serial = "{SERIAL}"
condition = "{CONDITION}"
received = {RECEIVED}
"""


def tiny_png() -> bytes:
    """A 1x1 PNG, written by hand (signature, IHDR, IDAT, IEND)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
    pixels = zlib.compress(b"\x00\xc0\x26\x2d")
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", pixels) + chunk(b"IEND", b"")


def lab_file(folder: Path, logo: bool = True) -> Path:
    (folder / "logo.png").write_bytes(tiny_png())
    text = f'[lab]\nname = "{LAB_NAME}"\naddress = """{ADDRESS[0]}\n{ADDRESS[1]}"""\n'
    text += f'accreditation_id = "{ACCREDITATION}"\n' + ('logo = "logo.png"\n' if logo else "")
    (folder / "lab.toml").write_text(text, encoding="utf-8")
    return folder / "lab.toml"


def _ok(argv: list[str], codes: tuple[int, ...] = (0,)) -> str:
    result = run_cli(argv)
    assert result.code in codes, result.err
    return result.err


def public_fingerprint(key_file: Path) -> str:
    """sha256 of the raw public key, first 16 hex digits (the fingerprint's definition, docs/records.md)."""
    from cryptography.hazmat.primitives import serialization

    key = serialization.load_pem_private_key(key_file.read_bytes(), password=None)
    raw = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)  # type: ignore[union-attr]
    return hashlib.sha256(raw).hexdigest()[:16]


@pytest.fixture(scope="module")
def issued(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A signed run stopped by its re-shoot budget, resumed after a rig check, finished and issued;
    its report as Markdown, HTML and JSON, and the store's own entries."""
    folder = tmp_path_factory.mktemp("report")
    keys = folder / "keys"
    (folder / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (folder / "bat.toml").write_text(BAT, encoding="utf-8")
    (folder / "wild.toml").write_text(WILD, encoding="utf-8")
    lab = lab_file(folder)
    db = ["--db", str(folder / "r.db")]
    with mock.patch.dict(os.environ, {"RIG_KEY_DIR": str(keys)}):
        _ok(["keys", "create", "--rig", "sim-wild"])
        _ok(["keys", "register", "--rig", "sim-wild", *db])
        start = ["certify", "--procedure", str(folder / "proc.toml"), "--bat", str(folder / "bat.toml")]
        err = _ok(
            [*start, "--sim", str(folder / "wild.toml"), *db, "--lab", str(lab), "--operator", OPERATOR], (3,)
        )
        run_id = err.split("rig certify --resume ")[1].split()[0]
        resume = ["certify", "--resume", run_id, "--sim", "ideal", "--rig-checked", "--who", CHECKER]
        _ok([*resume, "--why", "cannon seal replaced", *db], (0, 1))
    said = _ok(["report", run_id, "--issue", "--by", AUTHORISER, "--format", "json", *db])
    out: dict[str, Any] = {
        "run_id": run_id,
        "said": said,
        "fingerprint": public_fingerprint(keys / "sim-wild.key"),
    }
    for fmt in ("md", "html", "json"):
        target = folder / f"report.{fmt}"
        _ok(["report", run_id, "--format", fmt, "--output", str(target), *db])
        out[fmt] = target.read_text(encoding="utf-8")
    with Store.open(folder / "r.db") as store:
        out["entries"] = store.entries(run_id)
        out["issue"] = [e for e in store.entries(None) if e.kind == "ReportIssued"]
    return out


def _text(page: str) -> str:
    """The HTML's visible text, tags dropped and entities read (what a reader sees)."""
    body = page.split("<body>", 1)[1]
    return html.unescape(re.sub(r"<[^>]+>", " ", body))


def _flat(text: str) -> str:
    return re.sub(r"\s+", " ", text.replace("\\|", "|"))


def _expected(issued: dict[str, Any]) -> dict[str, list[str]]:
    """Each item of ISO/IEC 17025 7.8.2.1 and the values the report must show for it, from the inputs
    and the store's entries."""
    entries, issue = issued["entries"], issued["issue"]
    created = next(e for e in entries if e.kind == "RunCreated")
    started = next(e for e in entries if e.kind == "RunStarted")
    finished = next(e for e in entries if e.kind == "RunFinished")
    assert len(issue) == 1 and issue[0].payload["run_id"] == issued["run_id"]
    report_id = f"R-{issued['run_id'][:12]}"
    assert issue[0].payload["report_id"] == report_id
    # the result: the mean of the hits RunFinished names, to the decimals U gives (two significant digits)
    hits, big_u = finished.payload["hits"], finished.payload["U"]
    decimals = 1 - math.floor(math.log10(big_u))
    mean = statistics.fmean(hits)
    stops = [e for e in entries if e.kind in ("RunInterrupted", "RunResumed", "RigChecked")]
    return {
        "a title": ["Bat performance certificate", "Test report"],
        "b lab name and address": [LAB_NAME, ADDRESS[0], ADDRESS[1], ACCREDITATION],
        "c unique id and a clear end": [report_id, f"End of report {report_id}"],
        "d customer": [CUSTOMER],
        "e method": [started.payload["procedure"]["name"], started.payload["procedure"]["edition"]],
        "f item and condition": ["RPT-1", MAKER, MODEL, SERIAL, CONDITION],
        "g dates of receipt, test, issue": [RECEIVED, created.t_utc[:10], issue[0].t_utc[:10]],
        "h statement": ["The results relate only to the item tested"],
        "i results with units": [f"{mean:.{decimals}f} ± {big_u:.{2 - 1 - math.floor(math.log10(big_u))}f}"],
        "j deviations": ["run interrupted", "run resumed", f"by {CHECKER}: cannon seal replaced"]
        + [str(e.payload["reason"]) for e in stops if e.kind == "RunInterrupted"],
        "k person authorising": [f"authorised by {AUTHORISER}", OPERATOR],
    }


def test_the_checklist_of_iso_17025_7_8_2_1_is_in_the_html_and_the_markdown(issued: dict[str, Any]) -> None:
    expected = _expected(issued)
    for fmt, text in (("md", _flat(issued["md"])), ("html", _flat(_text(issued["html"])))):
        for item, values in expected.items():
            for value in values:
                assert _flat(value) in text, f"{fmt}: 7.8.2.1 {item}: {value!r} not in the report"
    # the first page carries them: everything above the technical annex
    for fmt, text in (("md", issued["md"]), ("html", _text(issued["html"]))):
        first = _flat(text.split("Technical annex")[0])
        for item in (
            "b lab name and address",
            "d customer",
            "g dates of receipt, test, issue",
            "k person authorising",
        ):
            assert all(_flat(v) in first for v in expected[item]), (fmt, item)
    assert issued["md"].rstrip().endswith(f"**End of report R-{issued['run_id'][:12]}.**")


def test_every_printed_page_is_to_carry_the_id_the_page_count_and_the_simulated_mark(
    issued: dict[str, Any],
) -> None:
    style = issued["html"].split("<style>")[1].split("</style>")[0]
    page = style[style.index("@page {\n") :]
    decoded = re.sub(r"\\([0-9a-f]{6})", lambda m: chr(int(m.group(1), 16)), page)
    assert f'"Report R-{issued["run_id"][:12]}"' in decoded
    assert '"page " counter(page) " of " counter(pages)' in page
    assert '"SIMULATED - NOT A CERTIFICATION"' in decoded and f'"{LAB_NAME}"' in decoded
    assert "DRAFT" not in decoded  # issued


def test_the_simulated_run_is_marked_in_its_banner_and_its_json(issued: dict[str, Any]) -> None:
    record = json.loads(issued["json"])
    assert record["simulated"] is True and record["simulated_notice"] == "SIMULATED - NOT A CERTIFICATION"
    banner = re.search(r'<div class="banner (\w+)"><div class="mark">([^<]*)</div>', issued["html"])
    assert banner is not None and banner.group(2) == "SIMULATED - NOT A CERTIFICATION"
    assert "> **SIMULATED - NOT A CERTIFICATION**\n>\n> **PASS" in issued["md"] or "> **FAIL" in issued["md"]


def test_the_record_holds_the_lab_the_operator_and_the_issue(issued: dict[str, Any]) -> None:
    record = json.loads(issued["json"])
    lab = record["lab"]
    assert (lab["name"], lab["address"], lab["accreditation_id"]) == (
        LAB_NAME,
        "\n".join(ADDRESS),
        ACCREDITATION,
    )
    assert base64.b64decode(lab["logo"]["data_b64"]) == tiny_png()
    assert lab["logo"]["sha256"] == hashlib.sha256(tiny_png()).hexdigest()
    assert f'src="data:image/png;base64,{lab["logo"]["data_b64"]}"' in issued["html"]
    assert record["tested_by"]["name"] == OPERATOR
    assert record["issue"]["by"] == AUTHORISER and record["issue"]["report_id"] == record["report_id"]
    assert f"issued report {record['report_id']}" in issued["said"]
    bat = record["bat"]
    assert (bat["customer"], bat["serial"], bat["received"]) == (CUSTOMER, SERIAL, RECEIVED)


def test_the_seal_names_the_rig_key_and_its_fingerprint(issued: dict[str, Any]) -> None:
    record = json.loads(issued["json"])
    fp = issued["fingerprint"]
    assert record["seal"]["signed"] is True and record["seal"]["fingerprint"] == fp
    assert record["seal"]["check"] == "valid"
    text = _flat(issued["md"])
    assert f"Signed with rig sim-wild's Ed25519 key, fingerprint {fp}" in text
    assert f"rig verify --run {issued['run_id']} --trusted-key sim-wild:{fp}" in text


def test_a_draft_says_so_and_a_second_issue_is_refused(tmp_path: Path) -> None:
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(BAT, encoding="utf-8")
    db = ["--db", str(tmp_path / "r.db")]
    start = ["certify", "--procedure", str(tmp_path / "proc.toml"), "--bat", str(tmp_path / "bat.toml")]
    _ok([*start, "--sim", "ideal", *db], (0, 1))
    md = run_cli(["report", "last", "--format", "md", "--output", str(tmp_path / "d.md"), *db])
    assert md.code == 0, md.err
    draft = (tmp_path / "d.md").read_text(encoding="utf-8")
    assert "| date of issue | DRAFT - NOT ISSUED |" in draft
    assert "no operator named (a scripted run: prompts answered by script" in draft
    assert "not named: no lab identity file was given" in draft
    _ok(["report", "last", "--issue", "--by", AUTHORISER, "--format", "json", *db])
    again = run_cli(["report", "last", "--issue", "--by", "someone else", "--format", "json", *db])
    assert again.code == 2 and "issued already" in again.err and len(again.err.strip().splitlines()) == 1
    alone = run_cli(["report", "last", "--issue", "--format", "json", *db])
    assert alone.code == 2 and "--by" in alone.err


@pytest.mark.parametrize(
    ("lab", "logo", "cause"),
    [
        ('[lab]\nname = "Lab"\n', None, "address"),
        ('[lab]\nname = "Lab\\u0007"\naddress = "x"\n', None, "printable"),
        ('[lab]\nname = "Lab"\naddress = "x"\nextra = 1\n', None, "extra"),
        ('name = "Lab"\n', None, "[lab]"),
        (
            '[lab]\nname = "Lab"\naddress = "x"\nlogo = "logo.svg"\n',
            b"<svg onload='x()'/>",
            "not a PNG or JPEG",
        ),
        (
            '[lab]\nname = "Lab"\naddress = "x"\nlogo = "logo.svg"\n',
            b"\x89PNG\r\n\x1a\n" + b"0" * 300_000,
            "larger",
        ),
        ('[lab]\nname = "Lab"\naddress = "x"\nlogo = "missing.png"\n', None, "no such file"),
    ],
)
def test_a_hostile_lab_file_is_refused_in_one_line_and_nothing_is_recorded(
    tmp_path: Path, lab: str, logo: bytes | None, cause: str
) -> None:
    (tmp_path / "lab.toml").write_text(lab, encoding="utf-8")
    if logo is not None:
        (tmp_path / "logo.svg").write_bytes(logo)
    (tmp_path / "bat.toml").write_text(BAT, encoding="utf-8")
    db = tmp_path / "r.db"
    argv = ["certify", "--procedure", "bbcor", "--bat", str(tmp_path / "bat.toml"), "--sim", "ideal"]
    result = run_cli([*argv, "--db", str(db), "--lab", str(tmp_path / "lab.toml")], db)
    lines = result.err.strip().splitlines()
    assert result.code == 2 and len(lines) == 1 and cause in lines[0], result.err
    assert "lab.toml" in lines[0] or "logo" in lines[0]
    if db.exists():
        with Store.open(db) as store:
            assert store.runs() == []


def test_rig_lab_names_the_file_and_lab_wins_over_it(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    env_lab = lab_file(tmp_path / "a", logo=False)
    given = tmp_path / "b" / "lab.toml"
    given.write_text('[lab]\nname = "Given Lab"\naddress = "1 Road"\n', encoding="utf-8")
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(BAT, encoding="utf-8")
    db = ["--db", str(tmp_path / "r.db")]
    start = [
        "certify",
        "--procedure",
        str(tmp_path / "proc.toml"),
        "--bat",
        str(tmp_path / "bat.toml"),
        "--sim",
        "ideal",
    ]
    names = []
    with mock.patch.dict(os.environ, {"RIG_LAB": str(env_lab)}):
        for extra in ([], ["--lab", str(given)]):
            _ok([*start, *db, *extra], (0, 1))
            out = tmp_path / "r.json"
            _ok(["report", "last", "--json", "--output", str(out), *db])
            names.append(json.loads(out.read_text(encoding="utf-8"))["lab"]["name"])
    assert names == [LAB_NAME, "Given Lab"]


def test_a_bat_file_without_the_new_fields_registers_as_before(tmp_path: Path) -> None:
    from rig.core.bat import BatSpec

    (tmp_path / "new.toml").write_text(BAT, encoding="utf-8")
    old = "\n".join(
        line
        for line in BAT.splitlines()
        if line.split(" = ")[0] not in {"customer", "maker", "model", "serial", "condition", "received"}
    )
    (tmp_path / "old.toml").write_text(old + "\n", encoding="utf-8")
    new, before = BatSpec.load(tmp_path / "new.toml"), BatSpec.load(tmp_path / "old.toml")
    # what the store registers: the bat's properties only, the same for both files
    assert new.registered() == before.registered()
    assert set(before.registered()) == {
        "id",
        "length_in",
        "weight_oz",
        "barrel",
        "hoop_hz",
        "moi_kgm2",
        "moi_u_kgm2",
        "balance_point_in",
    }


def test_a_real_rig_run_without_an_operator_named_lists_it_as_a_deviation() -> None:
    """Who performed the test is a report item (7.8.2.1): a run on a real rig that started without a
    name says so among the deviations; a simulated run, a named operator and an older record do not."""
    from rig.report.cert_report import deviation_rows

    unnamed = {"tested_by": {"name": None, "answered_by": "script"}, "simulated": False, "started_utc": "T0"}
    (row,) = deviation_rows(unnamed)
    assert row[0].startswith("no operator named when the run started") and row[1] == "T0"
    assert deviation_rows({**unnamed, "tested_by": {"name": "A. Tester", "answered_by": "script"}}) == []
    assert deviation_rows({**unnamed, "simulated": True}) == []
    assert deviation_rows({"simulated": False}) == []  # recorded before runs named their operator
