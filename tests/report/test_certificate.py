"""The certificate: verdict, every shot, anchor, figures; HTML self-contained, escaped and well formed."""

from __future__ import annotations

import base64
import copy
import math
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.protocols.procedure import Procedure
from rig.protocols.runner import ScriptedOperator
from rig.report.cert_doc import html_escape, md_escape
from rig.report.cert_plots import model_curve
from rig.report.certificate import NOT_CERTIFIED, render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def records(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """Records of runs on the simulated rig: pass, fail, interrupted, ring failure, BESR, BBS."""
    soft = SAMPLE_BAT.model_copy(update={"id": "SOFT-1800", "hoop_hz": 1800.0})
    # the lab's own barrel keeps 1800 Hz bats legal; the paper's generic barrel makes one hot (~0.60)
    hot = tmp_path_factory.mktemp("scene") / "hot.toml"
    hot.write_text('[[effects]]\nkind = "trampoline"\n', encoding="utf-8")
    runs = {
        "pass": ("bbcor", SAMPLE_BAT, "lab", None),
        "fail": ("bbcor", soft, str(hot), None),
        "interrupted": ("bbcor", SAMPLE_BAT, "faulty", None),
        "ring": ("bbcor", SAMPLE_BAT, "ideal", ScriptedOperator(answer=False, who="test")),
        "besr": ("besr", SAMPLE_BAT, "lab", None),
        "bbs": ("bbs", SAMPLE_BAT, "lab", None),
    }
    out = {}
    with Store.open(tmp_path_factory.mktemp("store") / "r.db") as store:
        for key, (proc, bat, scene, operator) in runs.items():
            outcome = certify(store, Procedure.load(proc), bat, sim_config(scene, bat=bat), operator=operator)
            out[key] = run_record(store, outcome.run_id)
    return out


class _Checker(HTMLParser):
    """Every element closed in order; collects image sources."""

    VOID = frozenset({"meta", "img", "br", "hr", "link", "input"})

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.images: list[str] = []
        self.doctype = False

    def handle_decl(self, decl: str) -> None:
        self.doctype = self.doctype or decl.lower() == "doctype html"

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.images.append(dict(attrs).get("src") or "")
        if tag not in self.VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()


def _check_html(text: str) -> _Checker:
    checker = _Checker()
    checker.feed(text)
    checker.close()
    assert checker.doctype and not checker.errors and not checker.stack, (checker.errors, checker.stack)
    return checker


def _shot_rows(md: str) -> set[int]:
    """Shot numbers in the first column of the Markdown shot tables."""
    return {int(m) for m in re.findall(r"^\| (\d+) \| (?:scan|certification) \|", md, flags=re.M)}


def test_markdown_certificate_of_a_passing_bat(records: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    rec = records["pass"]
    v, anchor = rec["verdict"], rec["anchor"]
    assert v["verdict"] == "PASS"
    md = render(rec, "md", figures_dir=tmp_path / "figs", output=tmp_path / "cert.md")
    assert md.startswith("# Bat performance certificate: NCAA BBCOR — bat SAMPLE-AL-33")
    assert rec["procedure"]["edition"] in md
    assert "> **PASS: BBCOR" in md
    d = 1 - math.floor(math.log10(v["U"]))  # U to two significant digits, the mean to match (GUM 7.2.6)
    assert f"{v['mean']:.{d}f} ± {v['U']:.{d}f}" in md and "| limit | 0.5 |" in md
    assert "Guarded acceptance (k = 2)" in md
    assert _shot_rows(md) == {s["index"] for s in rec["shots"]}  # every shot, nothing hidden
    assert f"rig verify --anchor {anchor['seq']}:{anchor['hash']}" in md
    budget_rows = re.findall(r"^\| (\w+) \| .* \| (?:systematic|random) \|", md, flags=re.M)
    shares = v["budget"]["outputs"]["bbcor"]["contributions"]
    assert budget_rows[0] == max(shares, key=shares.get)  # largest contribution first
    assert "I" in budget_rows  # the MOI, with its derived u, is an input of the budget
    assert "◀ this procedure" in md and "◀ chosen" in md
    assert f"{rec['cross_check']['predicted']:.4f}" in md
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert links == ["figs/location-scan.png", "figs/valid-hits.png", "figs/model-curve.png"]
    for link in links:
        assert (tmp_path / link).read_bytes().startswith(PNG)
    # the same record gives the same document
    assert render(rec, "md", figures_dir=tmp_path / "figs", output=tmp_path / "cert.md") == md


def test_html_is_standalone_well_formed_and_embeds_the_figures(
    records: dict[str, dict[str, Any]], tmp_path: Path
) -> None:
    rec = records["pass"]
    page = render(rec, "html", figures_dir=tmp_path / "figs")
    checker = _check_html(page)
    svg = "data:image/svg+xml;base64,"
    assert len(checker.images) == 3 and all(src.startswith(svg) for src in checker.images)
    for src in checker.images:  # vector figures that scale: a viewBox, drawn paths, no raster inside
        text = base64.b64decode(src[len(svg) :]).decode("utf-8")
        assert "<svg" in text and "viewBox=" in text and "<path" in text and "<image" not in text
    assert "<style>" in page and 'class="banner pass"' in page
    assert "@media print" in page and "break-inside: avoid" in page
    assert rec["anchor"]["hash"] in page
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == [
        "location-scan.png",
        "model-curve.png",
        "valid-hits.png",
    ]
    assert all(p.stat().st_size > 1000 for p in (tmp_path / "figs").iterdir())


def test_without_a_figures_folder_nothing_is_written(
    records: dict[str, dict[str, Any]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    rec = records["pass"]
    monkeypatch.chdir(tmp_path)
    md = render(rec, "md", output=tmp_path / "out" / "cert.md")
    assert "![" not in md and "> **PASS: BBCOR" in md  # the text, without figures
    page = render(rec, "html")
    assert len(_check_html(page).images) == 3  # drawn in memory
    assert page == render(rec, "html")  # no date or random id in the SVG: the same record, the same page
    assert list(tmp_path.iterdir()) == []
    # without an output path the links are absolute: right wherever the text is saved
    md = render(rec, "md", figures_dir=tmp_path / "figs")
    assert f"]({(tmp_path / 'figs' / 'valid-hits.png').as_posix()})" in md


def test_failing_bat_renders_fail(records: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    rec = records["fail"]
    assert rec["verdict"]["verdict"] == "FAIL"
    md = render(rec, "md", figures_dir=tmp_path)
    assert "> **FAIL: BBCOR" in md and "PASS:" not in md
    assert 'class="banner fail"' in render(rec, "html", figures_dir=tmp_path)


def test_interrupted_run_is_not_certified_and_lists_every_shot(
    records: dict[str, dict[str, Any]], tmp_path: Path
) -> None:
    rec = records["interrupted"]
    assert rec["verdict"] is None and rec["shots"]
    md = render(rec, "md", figures_dir=tmp_path)
    assert NOT_CERTIFIED in md and "PASS" not in md
    assert f"rig certify --resume {rec['run_id']} --sim faulty" in md
    assert _shot_rows(md) == {s["index"] for s in rec["shots"]}
    assert "LOST: " in md and "| interrupted |" in md
    checker = _check_html(render(rec, "html", figures_dir=tmp_path))
    assert len(checker.images) == 1  # the scan so far; no hits or model figure without a verdict


def test_failed_ring_check_renders_fail_with_its_reason(
    records: dict[str, dict[str, Any]], tmp_path: Path
) -> None:
    rec = records["ring"]
    assert rec["verdict"]["verdict"] == "FAIL" and not rec["shots"]
    md = render(rec, "md", figures_dir=tmp_path)
    assert "> **FAIL — ring check failed" in md and "| ring-before | " in md
    _check_html(render(rec, "html", figures_dir=tmp_path))


@pytest.mark.parametrize(("key", "label"), [("besr", "BESR"), ("bbs", "BBS")])
def test_other_metrics_render(
    records: dict[str, dict[str, Any]], tmp_path: Path, key: str, label: str
) -> None:
    rec = records[key]
    md = render(rec, "md", figures_dir=tmp_path)
    assert f"> **{rec['verdict']['verdict']}: {label} " in md
    assert _shot_rows(md) == {s["index"] for s in rec["shots"]}
    assert "## Uncertainty budget of the mean" in md and "## Accuracy against lab time" in md
    if key == "bbs":
        assert "m/s (k = 2)" in md and "dBBS/de_A" in md
    _check_html(render(rec, "html", figures_dir=tmp_path))


def test_missing_optional_parts_do_not_crash(records: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    rec = copy.deepcopy(records["pass"])
    rec["cross_check"] = None
    for key in ("budget", "tradeoff", "definition", "zone"):
        rec["verdict"].pop(key)
    rec["moi"], rec["location"], rec["software"], rec["environment"] = None, None, None, []
    md = render(rec, "md", figures_dir=tmp_path)
    assert "No model cross-check in the record." in md and "## Uncertainty budget" not in md
    no_hoop = copy.deepcopy(records["pass"])
    no_hoop["bat"]["hoop_hz"] = None
    no_hoop["cross_check"] = {
        "predicted": None,
        "note": "no hoop frequency in the bat file: no model cross-check",
    }
    assert "no hoop frequency in the bat file" in render(no_hoop, "md", figures_dir=tmp_path)


def test_model_curve_agrees_with_the_recorded_cross_check(records: dict[str, dict[str, Any]]) -> None:
    rec = records["pass"]
    values, rigid = model_curve(rec, np.array([rec["bat"]["hoop_hz"]]))  # type: ignore[misc]
    assert values[0] == pytest.approx(rec["cross_check"]["predicted"], rel=1e-6)
    assert rigid < values[0]  # at 3600 Hz the trampoline effect still adds to a rigid barrel


def test_record_text_is_escaped() -> None:
    hostile = '<script>alert("x")</script> & R&amp;D | col'
    assert html_escape(hostile) == "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; R&amp;amp;D | col"
    assert "<script" not in md_escape(hostile) and "&lt;script>" in md_escape(hostile)
    assert "\\|" in md_escape(hostile, cell=True)
    assert md_escape("mean + 2 u <= limit") == "mean + 2 u <= limit"  # '<=' stays readable


def test_html_escapes_text_taken_from_the_record(records: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    rec = copy.deepcopy(records["pass"])
    rec["rig"]["name"] = "<script>alert(1)</script>"
    rec["operator"][0]["who"] = "<b>mallory</b>"
    page = render(rec, "html", figures_dir=tmp_path)
    assert "<script>" not in page and "<b>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    _check_html(page)
    md = render(rec, "md", figures_dir=tmp_path)
    assert "<script>" not in md and "&lt;script>alert(1)&lt;/script>" in md


def test_unknown_format_is_refused(records: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="pdf"):
        render(records["pass"], "pdf", figures_dir=tmp_path)
