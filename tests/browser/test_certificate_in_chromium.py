"""The HTML certificate in a real browser: Debian's chromium, headless, renders it, shows the verdict
in its first screen, draws the SVG figures, and prints it to PDF with the report id, "page x of y"
and (a simulated run) SIMULATED - NOT A CERTIFICATION on every page. The PDF's text is read with
pypdf (a test dependency: Chromium's PDFs hold compressed, subset-font text no regex reads).

Opt-in: skipped when chromium is absent, with the hint; `RIG_BROWSER_TESTS=1` makes the test run
tests/browser/setup.sh first (apt-get install chromium, as root), and fail rather than skip.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import unicodedata
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE, run_cli

HERE = Path(__file__).resolve().parent
HINT = "chromium is not installed: run `sh tests/browser/setup.sh` as root (or set RIG_BROWSER_TESTS=1)"
PASS_BORDER = (0x1A, 0x7F, 0x37)  # .pass border colour of the verdict banner (rig.report.cert_doc)
FAIL_BORDER = (0xC0, 0x26, 0x2D)

pytestmark = pytest.mark.browser


def _chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None and os.environ.get("RIG_BROWSER_TESTS") == "1":
        subprocess.run(["sh", str(HERE / "setup.sh")], check=False, timeout=900)
        found = shutil.which("chromium") or shutil.which("chromium-browser")
        if found is None:
            pytest.fail(HINT)
    if found is None:
        pytest.skip(HINT)
    return found


def _headless(browser: str, *args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars"]
    profile = f"--user-data-dir={cwd / 'profile'}"
    return subprocess.run(
        [browser, *flags, profile, *args], capture_output=True, text=True, cwd=cwd, timeout=180, check=False
    )


@pytest.fixture(scope="module")
def certificate(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """An HTML certificate of a short simulated run, written by `rig report`, with its record."""
    import json

    folder = tmp_path_factory.mktemp("browser")
    (folder / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (folder / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    db = folder / "r.db"
    argv = ["certify", "--procedure", str(folder / "proc.toml"), "--bat", str(folder / "bat.toml")]
    assert run_cli([*argv, "--sim", "ideal", "--db", str(db)], db).code in (0, 1)
    page = folder / "certificate.html"
    assert run_cli(["report", "last", "--db", str(db), "--format", "html", "--output", str(page)]).code == 0
    record_file = folder / "record.json"
    assert run_cli(["report", "last", "--db", str(db), "--json", "--output", str(record_file)]).code == 0
    return {"page": page, "record": json.loads(record_file.read_text(encoding="utf-8")), "folder": folder}


def test_the_browser_shows_the_verdict_and_the_figures(certificate: dict[str, Any]) -> None:
    browser = _chromium()
    folder, page = certificate["folder"], certificate["page"]
    verdict = certificate["record"]["verdict"]["verdict"]
    dom = _headless(browser, "--dump-dom", page.as_uri(), cwd=folder)
    assert dom.returncode == 0, dom.stderr[-500:]
    banner = re.search(
        r'<div class="banner (\w+)"><div class="mark">([^<]*)</div><div class="title">([^<]*)</div>',
        dom.stdout,
    )
    assert banner is not None and banner.group(1) == verdict.lower() and banner.group(3).startswith(verdict)
    assert banner.group(2) == "SIMULATED - NOT A CERTIFICATION"  # the run is on the simulated rig
    assert len(re.findall(r'<img src="data:image/svg\+xml;base64,', dom.stdout)) == 3

    shot = folder / "first-screen.png"
    done = _headless(browser, f"--screenshot={shot}", "--window-size=1200,900", page.as_uri(), cwd=folder)
    assert done.returncode == 0 and shot.is_file(), done.stderr[-500:]
    import matplotlib.image

    pixels = (matplotlib.image.imread(shot)[:, :, :3] * 255).round().astype(int)
    border = np.array(PASS_BORDER if verdict == "PASS" else FAIL_BORDER)
    hits = np.all(np.abs(pixels - border) <= 8, axis=2)
    assert hits.sum() > 1000, "the verdict banner's border is not on the first screen"  # a 3 px frame
    other = np.array(FAIL_BORDER if verdict == "PASS" else PASS_BORDER)
    assert np.all(np.abs(pixels - other) <= 8, axis=2).sum() < 50  # and not the other verdict's


def test_the_certificate_prints_to_pdf(certificate: dict[str, Any]) -> None:
    browser = _chromium()
    folder, page = certificate["folder"], certificate["page"]
    pdf = folder / "certificate.pdf"
    done = _headless(browser, f"--print-to-pdf={pdf}", "--no-pdf-header-footer", page.as_uri(), cwd=folder)
    assert done.returncode == 0 and pdf.is_file(), done.stderr[-500:]
    data = pdf.read_bytes()
    pages = len(re.findall(rb"/Type\s*/Page(?!s)", data))
    assert data.startswith(b"%PDF-") and 2 <= pages <= 30, pages
    # A4 pages (the print CSS's @page): 595 x 842 points
    sizes = set(re.findall(rb"/MediaBox\s*\[\s*0\s+0\s+([\d.]+)\s+([\d.]+)\s*\]", data))
    assert sizes and all(abs(float(w) - 595.3) < 2 and abs(float(h) - 841.9) < 2 for w, h in sizes), sizes


def _squeezed(text: str) -> str:
    """Text without whitespace and with ligatures undone (NFKC: the printed font may set "ff" as one
    glyph, U+FB00): the PDF's text extraction spaces words as the layout placed them."""
    return re.sub(r"\s+", "", unicodedata.normalize("NFKC", text))


def test_every_printed_page_carries_the_report_id_its_number_and_the_simulated_mark(
    certificate: dict[str, Any],
) -> None:
    pypdf = pytest.importorskip("pypdf")
    browser = _chromium()
    folder, page = certificate["folder"], certificate["page"]
    pdf = folder / "marked.pdf"
    done = _headless(browser, f"--print-to-pdf={pdf}", "--no-pdf-header-footer", page.as_uri(), cwd=folder)
    assert done.returncode == 0 and pdf.is_file(), done.stderr[-500:]
    pages = [p.extract_text() or "" for p in pypdf.PdfReader(pdf).pages]
    report_id = f"R-{certificate['record']['run_id'][:12]}"
    assert len(pages) >= 3  # the report, then the technical annex on a page of its own
    for number, text in enumerate(pages, 1):
        flat = _squeezed(text)
        assert _squeezed(f"page {number} of {len(pages)}") in flat, (number, text[:300])
        assert _squeezed(f"Report {report_id}") in flat, number
        assert _squeezed("SIMULATED - NOT A CERTIFICATION") in flat, number
        assert _squeezed("DRAFT - NOT ISSUED") in flat, number  # the run's report is not issued
    assert "Technical annex" in "".join(pages[1:]) and "Technical annex" not in pages[0]
    assert _squeezed(f"End of report {report_id}.") in _squeezed(pages[-1])
