"""The certificate's balls: each valid hit's ball and its hit count, the lot, the ball law, each hit's
correction and the ball's budget terms, checked against the run's own log (not the record's rendering);
and an older record without any of it."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify, history
from rig.core.bat import BatSpec
from rig.protocols.ball_terms import BallTerms
from rig.protocols.procedure import Procedure
from rig.report.cert_doc import html_escape
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store
from tests.report.test_certificate import _check_html

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
LAW = {"m1": 0.145, "k1": 6.0e7, "c1": 5200.0, "a": 0.66, "b": 0.52}
TERMS = BallTerms(
    lot="L1",
    source="lot L1: ball-cor run of the test (wear, spread); air sensitivities measured",
    wear_measured=True,
    wear_per_hit=-0.0003,
    wear_per_hit_u=0.0001,
    conditions_measured=True,
    cor_per_c=0.0012,
    cor_per_c_u=0.0004,
    cor_per_pct_rh=-0.0005,
    cor_per_pct_rh_u=0.0002,
    plate_cor=0.482,
    sd_between_balls=0.002,
    temp_c=20.0,
    rh_pct=50.0,
    law=LAW,
)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], list[Any]]:
    """A BBCOR certification on the lab rig with a named lot's terms: its record and its log."""
    with Store.open(tmp_path_factory.mktemp("store") / "r.db") as store:
        bat = SAMPLE_BAT
        bbcor = Procedure.load("bbcor")
        # a new ball every 6 hits: the valid hits span two balls whatever the scan took
        six = bbcor.model_copy(update={"ball": bbcor.ball.model_copy(update={"replace_after_hits": 6})})
        out = certify(
            store,
            six,
            bat,
            sim_config("lab", bat=bat),
            ball=TERMS.model_dump(mode="json"),
        )
        return run_record(store, out.run_id), history(store, out.run_id)


def _section(md: str, heading: str) -> str:
    """The text under a heading, up to the next heading of the same or a higher level."""
    level = len(heading) - len(heading.lstrip("#"))
    start = md.index(heading + "\n")
    rest = md[start + len(heading) :]
    end = re.search(rf"^#{{1,{level}}} ", rest, flags=re.M)
    return rest[: end.start()] if end else rest


def _rows(text: str) -> list[list[str]]:
    """The cells of every table row (header and rule lines left out)."""
    out = []
    for line in text.splitlines():
        if line.startswith("| ") and not line.startswith("|---"):
            out.append([c.strip() for c in line.strip().strip("|").split(" | ")])
    return out[1:] if out else out


def _close(cell: str, value: float) -> bool:
    """A printed number equals `value` to the places printed."""
    places = len(cell.split(".")[1]) if "." in cell else 0
    return abs(float(cell) - value) <= 0.5 * 10.0**-places + 1e-12


def _expected_balls(log: list[Any]) -> dict[int, tuple[str, int]]:
    """Each fired shot's ball and its hit count with that shot, counted from the log itself: the
    ball's earlier shots that reached the gates (a new ball, announced by BallReplaced, starts at 1)."""
    hits: dict[str, int] = {}
    out = {}
    for e in log:
        if e.kind != "ShotFired":
            continue
        ball = e.data["ball"]
        out[e.data["index"]] = (ball, hits.get(ball, 0) + 1)
        if e.data.get("crossings"):
            hits[ball] = hits.get(ball, 0) + 1
    return out


def _air(log: list[Any]) -> dict[int, tuple[float, float]]:
    return {
        e.data["index"]: (e.data["temperature_c"], e.data["humidity_pct"])
        for e in log
        if e.kind == "ShotRequested"
    }


def test_the_record_and_its_json_carry_the_ball_terms_and_each_shots_ball(
    run: tuple[dict[str, Any], list[Any]],
) -> None:
    rec, log = run
    doc = json.loads(json.dumps(rec, allow_nan=False))  # what `rig report --format json` prints
    assert doc["ball"] == TERMS.model_dump(mode="json")
    fired = {e.data["index"]: e.data for e in log if e.kind == "ShotFired"}
    air = _air(log)
    for s in doc["shots"]:
        assert (s["raw"]["ball"], s["raw"]["ball_hits"]) == (
            fired[s["index"]]["ball"],
            fired[s["index"]]["ball_hits"],
        )
        assert (s["temperature_c"], s["humidity_pct"]) == air[s["index"]]
    assert len(doc["verdict"]["ball"]["corrections"]) == doc["verdict"]["n_hits"]


def test_valid_hits_name_each_ball_and_its_hit_count(run: tuple[dict[str, Any], list[Any]]) -> None:
    rec, log = run
    expected = _expected_balls(log)
    assert len({ball for ball, _ in expected.values()}) >= 2, "the run should use more than one ball"
    md = render(rec, "md")
    table = {int(r[0]): r[3] for r in _rows(_section(md, "## Valid hits")) if r[0].isdigit()}
    valid = [s["index"] for s in rec["shots"] if s["status"] == "valid"]
    assert sorted(table) == valid
    assert table == {i: f"{expected[i][0]} (hit {expected[i][1]})" for i in valid}
    page = render(rec, "html")
    _check_html(page)
    for i in valid:
        assert f"<td>{html_escape(table[i])}</td>" in page


def test_the_balls_section_shows_the_lot_the_law_and_each_hits_correction(
    run: tuple[dict[str, Any], list[Any]],
) -> None:
    rec, log = run
    v, vb = rec["verdict"], rec["verdict"]["ball"]
    md = render(rec, "md")
    balls = _section(md, "## Balls")
    items = dict(r for r in _rows(balls.split("###")[0]) if len(r) == 2)
    assert items["lot"] == "L1"
    assert items["source of the ball terms"] == TERMS.source
    assert items["ball law in use"] == "fitted ball law: " + ", ".join(
        f"{k} = {v:.5g}" for k, v in LAW.items()
    )
    assert items["nominal condition (conditioning)"] == "20.0 °C, 50 % RH"
    assert items["wear (per hit of a ball)"].startswith("corrected: -0.000300 ± 0.0001 plate COR per hit")
    assert items["the lab's air"].startswith("corrected to the nominal: +0.001200 ± 0.0004 plate COR per °C")
    plate = "lot's COR on the flat plate at 60 mph (ball-cor; at the tests' mean hit count, its nominal air)"
    assert _close(items[plate], 0.482)

    # each valid hit of the result, its ball, its correction from its own hits and air (the log's)
    expected, air = _expected_balls(log), _air(log)
    hits = _rows(_section(md, "### Each valid hit's ball"))
    result = [s for s in rec["shots"] if s["status"] == "valid" and s["purpose"] == "valid"]
    assert [int(r[0]) for r in hits] == [s["index"] for s in result]
    g = vb["g"]
    for row, shot, corrected in zip(hits, result, v["hits"], strict=True):
        ball, n = expected[shot["index"]]
        t, rh = air[shot["index"]]
        assert row[1] == f"{ball} (hit {n})"
        assert row[2] == f"{t:.1f} °C, {rh:.0f} % RH"
        own = -g * (
            TERMS.wear_per_hit * (n - 1)
            + TERMS.cor_per_c * (t - TERMS.temp_c)
            + TERMS.cor_per_pct_rh * (rh - 50.0)
        )
        assert _close(row[4], own)  # this hit's own correction, not its neighbour's
        assert _close(row[3], shot["metric"]) and _close(row[5], corrected)
        assert corrected == pytest.approx(shot["metric"] + own, abs=1e-12)
    assert f"Balls of the result: {', '.join(vb['balls'])}." in balls

    # the ball's terms in the budget, as the verdict has them
    budget = {r[0]: r[2] for r in _rows(_section(md, "### The ball in the budget"))}
    for term in ("wear", "conditions", "spread", "ratio"):
        assert float(budget[term]) == pytest.approx(vb[f"u_{term}"], rel=0.05)
    assert float(budget["ball"]) == pytest.approx(vb["u"], rel=0.05)
    assert float(budget["measurement"]) == pytest.approx(vb["u_measurement"], rel=0.05)
    assert float(budget["result"]) == pytest.approx(v["u"], rel=0.005)
    assert f"g = dBBCOR/d(plate COR) = {g:.4g}" in balls

    page = render(rec, "html")
    _check_html(page)
    assert "<h2>Balls</h2>" in page and "<td>L1</td>" in page
    assert html_escape(TERMS.source) in page


def test_assumed_terms_say_so(run: tuple[dict[str, Any], list[Any]]) -> None:
    rec = copy.deepcopy(run[0])
    rec["ball"] = BallTerms.model_validate({}).model_dump(mode="json")  # what a run given no terms records
    md = render(rec, "md")
    items = dict(r for r in _rows(_section(md, "## Balls").split("###")[0]) if len(r) == 2)
    assert items["lot"] == "no lot named: assumed defaults [U]"
    assert items["ball law in use"] == "the founding paper's constants"
    assert items["wear (per hit of a ball)"].startswith("not corrected:")
    assert items["the lab's air"].startswith("not corrected:")
    assert not [k for k in items if k.startswith("lot's COR on the flat plate")]  # not measured: not printed


def test_a_record_without_ball_information(run: tuple[dict[str, Any], list[Any]]) -> None:
    old = copy.deepcopy(run[0])
    del old["ball"], old["verdict"]["ball"]
    for s in old["shots"]:
        for key in ("ball", "ball_hits"):
            s["raw"].pop(key, None)
        s.pop("temperature_c", None), s.pop("humidity_pct", None)
    md = render(old, "md")
    table = {int(r[0]): r[3] for r in _rows(_section(md, "## Valid hits")) if r[0].isdigit()}
    assert table == {s["index"]: str(s["raw"]["ball_number"]) for s in old["shots"] if s["status"] == "valid"}
    assert "## Balls" not in md  # as such records always reported
    assert "the ball's terms" not in _section(md, "## Uncertainty budget of the mean")
    for s in old["shots"]:  # nothing at all about the ball: a dash
        s["raw"].pop("ball_number")
    md = render(old, "md")
    assert set(
        {int(r[0]): r[3] for r in _rows(_section(md, "## Valid hits")) if r[0].isdigit()}.values()
    ) == {"—"}
    _check_html(render(old, "html"))


def test_terms_without_a_verdict_show_the_lot_and_correct_nothing(
    run: tuple[dict[str, Any], list[Any]],
) -> None:
    rec = copy.deepcopy(run[0])
    rec["verdict"] = None
    balls = _section(render(rec, "md"), "## Balls")
    assert "| lot | L1 |" in balls and "Each valid hit's ball" not in balls
    assert "No verdict: no hit is corrected for its ball" in balls
