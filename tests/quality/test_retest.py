"""A retained bat certified again: the run records the bat's earlier result when it is created, and
its certificate compares the two by E_n (checked here by hand from both runs' records)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from rig.certification import certify
from rig.report.cert_doc import to_markdown
from rig.report.cert_retest import retest_blocks
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store
from tests.instruments.test_identity import BAT, _procedure
from tests.quality.test_compare_cli import rig


def test_a_retest_records_the_earlier_result_and_its_certificate_gives_en(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    with Store.open(db) as store:
        first = certify(store, _procedure(), BAT, sim_config("ideal", bat=BAT, session="one"))
        again = certify(store, _procedure(), BAT, sim_config("ideal", bat=BAT, session="two"))
        records = [run_record(store, run.run_id) for run in (first, again)]
        created = store.entries(again.run_id, kinds=["RunCreated"])[0].payload
    one, two = records
    assert "retest_of" not in one  # a first test
    assert created["meta"]["retest_of"] == two["retest_of"]  # in the hash-chained record itself
    earlier = two["retest_of"]
    assert earlier["run_id"] == first.run_id and earlier["started_utc"] == one["started_utc"]
    assert (earlier["mean"], earlier["U"], earlier["verdict"]) == (
        one["verdict"]["mean"],
        one["verdict"]["U"],
        one["verdict"]["verdict"],
    )
    x, u_x, ref, u_ref = (
        two["verdict"]["mean"],
        two["verdict"]["U"],
        one["verdict"]["mean"],
        one["verdict"]["U"],
    )
    en = (x - ref) / math.sqrt(u_x**2 + u_ref**2)
    text = render(two, "md")
    assert "## Retest of a retained item" in text and f"in run {first.run_id}" in text
    assert f"E_n = {en:+.2f}: {'satisfactory' if abs(en) <= 1 else 'unsatisfactory'}" in text
    assert "Retest" not in render(one, "md")
    html = render(two, "html")
    assert "Retest of a retained item" in html
    # rig compare on the store gives the same E_n
    code, out, err = rig("compare", "--db", str(db), "--json")
    assert code == 0, err
    (pair,) = json.loads(out)["pairs"]
    assert (pair["x"]["run_id"], pair["X"]["run_id"]) == (again.run_id, first.run_id)
    assert pair["E_n"] == en


def test_another_procedure_or_bat_is_no_retest(tmp_path: Path) -> None:
    other_bat = BAT.model_copy(update={"id": "OTHER-1"})
    besr = _procedure().model_copy(update={"standard": "besr"})
    with Store.open(tmp_path / "r.db") as store:
        certify(store, _procedure(), BAT, sim_config("ideal", bat=BAT))
        runs = [
            certify(store, _procedure(), other_bat, sim_config("ideal", bat=other_bat)),
            certify(store, besr, BAT, sim_config("ideal", bat=BAT)),
        ]
        records = [run_record(store, r.run_id) for r in runs]
    assert all("retest_of" not in r for r in records)


def test_the_section_by_hand_and_none_without_a_result() -> None:
    earlier = {
        "run_id": "abc",
        "started_utc": "2026-01-01T00:00:00+00:00",
        "mean": 0.45,
        "U": 0.01,
        "verdict": "PASS",
    }
    # by hand: (0.47 - 0.45) / sqrt(0.012^2 + 0.01^2) = 0.02 / 0.0156205 = 1.28: unsatisfactory
    done = {"retest_of": earlier, "verdict": {"mean": 0.47, "U": 0.012, "verdict": "PASS"}}
    text = to_markdown(retest_blocks(done), None)
    assert "E_n = +1.28: unsatisfactory" in text and "| earlier result (X) | 0.450 | 0.010 |" in text
    assert "| this result (x) | 0.470 | 0.012 |" in text
    assert (
        retest_blocks({"retest_of": earlier, "verdict": None}) == []
    )  # interrupted: no earlier result shown
    assert retest_blocks({"verdict": {"mean": 0.47, "U": 0.012}}) == []  # a first test
    no_u = {"retest_of": {**earlier, "U": None}, "verdict": done["verdict"]}
    assert "No E_n: the earlier result has no expanded uncertainty" in to_markdown(retest_blocks(no_u), None)
