"""The certificate's budget table and its "largest contribution" are on the result's u, every term
included (the measurement's inputs, the hits' scatter, the ball's terms), checked against the record's
own numbers; the lab-time table says which U is the measurement's and shows the result's beside it."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path

import pytest

from rig.cli import main

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
NAME = "log-8802354"
RUNS: dict[str, str] = json.loads((FIXTURES / f"{NAME}.runs.json").read_text())


def _cli(*argv: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        assert main(list(argv)) == 0
    return out.getvalue()


def budget_rows(md: str) -> dict[str, tuple[str, float]]:
    """{key: (u column, share in %)} of the certificate's budget table."""
    section = md.split("## Uncertainty budget of the mean", 1)[1].split("###", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 5 and cells[4].endswith(" %"):
            rows[cells[0]] = (cells[2], float(cells[4].removesuffix(" %")))
    return rows


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[dict, str]]:  # type: ignore[type-arg]
    db = tmp_path_factory.mktemp("shares") / f"{NAME}.db"
    shutil.copyfile(FIXTURES / f"{NAME}.db", db)
    return {
        name: (
            json.loads(_cli("report", RUNS[name], "--format", "json", "--db", str(db))),
            _cli("report", RUNS[name], "--format", "md", "--db", str(db)),
        )
        for name in ("bbs", "bbcor_lot")
    }


@pytest.mark.parametrize("name", ["bbs", "bbcor_lot"])
def test_the_shares_are_of_the_results_u_and_name_its_largest_term(
    reports: dict[str, tuple[dict, str]],  # type: ignore[type-arg]
    name: str,
) -> None:
    record, md = reports[name]
    v = record["verdict"]
    ball = v["ball"]
    rows = budget_rows(md)
    assert sum(share for _, share in rows.values()) == pytest.approx(100.0, abs=0.5)
    # each ball term's share is its variance over the result's u² (the record's own numbers)
    terms = {k: ball[f"u_{k}"] ** 2 / v["u"] ** 2 for k in ("wear", "conditions", "spread") if ball[f"u_{k}"]}
    for key, share in terms.items():
        assert rows[key][1] == pytest.approx(100 * share, rel=0.01, abs=0.01)
    largest = max(rows, key=lambda k: rows[k][1])
    assert largest in terms  # the ball dominates both runs' u
    words = {"wear": "wear within each ball", "conditions": "the lab's air", "spread": "spread between"}
    lead = re.search(r"Largest contribution: (.*?), ([0-9.]+) % of the result's u²", md)
    assert lead is not None and words[largest] in lead[1]
    assert float(lead[2]) == pytest.approx(100 * terms[largest], rel=0.01)


def test_the_lab_time_table_shows_the_measurement_part_and_the_results_u(
    reports: dict[str, tuple[dict, str]],  # type: ignore[type-arg]
) -> None:
    record, md = reports["bbs"]
    section = md.split("## Accuracy against lab time", 1)[1].split("\n## ", 1)[0]
    assert "| U (measurement) | U (result) |" in section
    this = next(line for line in section.splitlines() if "this procedure" in line)
    cells = [c.strip() for c in this.strip("|").split("|")]
    assert float(cells[4]) == pytest.approx(record["verdict"]["U"], rel=0.01)  # the certified U
    assert float(cells[3]) < record["verdict"]["U"] / 10  # the measurement's alone is far smaller
