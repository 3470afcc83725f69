"""On the simulated lab: 20 check runs build the charts; a worn ball lot (the balls' damping c1 raised
0.25 %) is a drift the EWMA signals within the run length its design predicts; certification is refused
until the signal is acknowledged, and the acknowledgement is on the next certificate.

One store for the whole module (the runs take about a second each).
"""

from __future__ import annotations

import io
import itertools
import json
import math
import shutil
import tomllib
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from rig.quality.charts import ewma_arl, ewma_run_length_quantile
from rig.simulators.scene import SCENES_DIR
from tests.unit.clirun import QUICK_PROCEDURE, main, run_cli

HITS = 4
PHASE_I = 20
DRIFT_RUNS = 5
WEAR = 1.0025  # the worn lot's c1 against the lab's
REF_BAT = """\
[bat]
id = "REF-CHECK-1"
length_in = 33.0
weight_oz = 30.0
barrel = "aluminium"
hoop_hz = 3600.0
balance_point_in = 22.0
moi_kgm2 = 0.19
moi_u_kgm2 = 0.0005
"""


def _json(argv: list[str]) -> object:
    out = io.StringIO()
    with redirect_stdout(out):
        code = main(argv)
    assert code == 0, argv
    return json.loads(out.getvalue())


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """A store with 20 in-control check runs, then DRIFT_RUNS with worn balls (same rig, sim-lab)."""
    root = tmp_path_factory.mktemp("checklab")
    db, bat = root / "lab.db", root / "ref.toml"
    bat.write_text(REF_BAT)
    worn = root / "worn" / "lab.toml"  # named lab.toml: the same rig, sim-lab, with another ball lot
    worn.parent.mkdir()
    shutil.copy(SCENES_DIR / "lab.toml", worn)
    c1 = tomllib.loads((SCENES_DIR / "lab.toml").read_text()).get("ball", {}).get("c1", 5000.0)
    with worn.open("a") as f:
        f.write(f"\n[ball]\nc1 = {c1 * WEAR!r}\n")
    base = ["check", "--bat", str(bat), "--db", str(db), "--hits", str(HITS), "--json"]
    before = [_json([*base, "--sim", "lab"]) for _ in range(PHASE_I)]
    after = [_json([*base, "--sim", str(worn)]) for _ in range(DRIFT_RUNS)]
    return {"root": root, "db": db, "before": before, "after": after}


def _chart(lab: dict[str, object]) -> dict[str, object]:
    charts = _json(["check", "chart", "--db", str(lab["db"]), "--json"])
    assert isinstance(charts, list) and len(charts) == 1
    return charts[0]


def test_twenty_check_runs_build_the_chart(lab: dict[str, object]) -> None:
    before = lab["before"]
    assert isinstance(before, list)
    assert [b["state"].startswith("building phase I") for b in before[:-1]] == [True] * (PHASE_I - 1)
    assert before[-1]["state"] == "in control" and before[-1]["rig"] == "sim-lab"
    chart = _chart(lab)
    means = [p["mean"] for p in chart["points"]][:PHASE_I]
    hits = [b["hits"] for b in before]
    # independently: the means of the recorded hits, their centre and moving-range sigma
    assert means == pytest.approx([sum(h) / HITS for h in hits], abs=1e-12)
    assert chart["centre"] == pytest.approx(sum(means) / PHASE_I)
    mr = sum(abs(b - a) for a, b in itertools.pairwise(means)) / (PHASE_I - 1)
    assert chart["sigma"] == pytest.approx(mr * math.sqrt(math.pi) / 2)
    assert chart["phase_i_sessions"] == PHASE_I and chart["ewma"]["lambda"] == 0.2


def test_a_worn_ball_lot_signals_within_the_ewma_design(lab: dict[str, object]) -> None:
    chart = _chart(lab)
    drift = [p["mean"] for p in chart["points"]][PHASE_I:]
    shift = (sum(drift) / len(drift) - chart["centre"]) / chart["sigma"]  # in sigmas of the means
    arl, q99 = ewma_arl(shift), ewma_run_length_quantile(shift, 0.99)
    first = min(s["index"] for s in chart["signals"] if s["rule"] == "EWMA") - PHASE_I
    print(
        f"worn lot: shift {shift:.2f} sigma, predicted ARL {arl:.2f}, 99 % within {q99}; signalled at {first}"
    )
    assert shift < -1.0  # a worn ball rebounds less: a real, downward shift
    assert arl < DRIFT_RUNS  # the design expects a signal within the runs made
    assert 1 <= first <= q99


def test_certification_is_refused_until_acknowledged_and_the_certificate_says_so(
    lab: dict[str, object],
) -> None:
    root, db = lab["root"], lab["db"]
    assert isinstance(root, Path)
    proc, bat = root / "quick.toml", root / "b1.toml"
    proc.write_text(QUICK_PROCEDURE)
    bat.write_text((root / "ref.toml").read_text().replace("REF-CHECK-1", "B-CUSTOMER"))
    certify = ["certify", "--procedure", str(proc), "--bat", str(bat), "--sim", "lab", "--db", str(db)]
    refused = run_cli(certify, db)
    assert refused.code == 2, refused.err
    line = refused.err.strip()
    assert "\n" not in line and "not acknowledged" in line and "sim-lab" in line
    assert f"session {PHASE_I + 1}" in line or f"session {PHASE_I + 2}" in line  # names the session
    assert run_cli(["check", "ack", "--db", str(db), "--who", "Q. Manager"], db).code == 2  # no --why
    acked = run_cli(["check", "ack", "--db", str(db), "--who", "Q. Manager", "--why", "lot replaced"], db)
    assert acked.code == 0, acked.err
    assert run_cli(["check", "ack", "--db", str(db), "--who", "x", "--why", "y"], db).code == 2  # none open
    done = run_cli(certify, db)
    assert done.code in (0, 1), done.err
    report = io.StringIO()
    with redirect_stdout(report):
        assert main(["report", "last", "--db", str(db), "--format", "md"]) == 0
    text = report.getvalue()
    assert "Quality control" in text and "Q. Manager" in text and "lot replaced" in text
    record = _json(["report", "last", "--db", str(db), "--format", "json"])
    assert isinstance(record, dict) and record["check_ack"]["who"] == "Q. Manager"
    chart = _chart(lab)
    assert chart["signals"] and all(s["acknowledged"] for s in chart["signals"])


def test_the_plot_and_bad_input(lab: dict[str, object]) -> None:
    root, db = lab["root"], lab["db"]
    assert isinstance(root, Path)
    assert run_cli(["check", "chart", "--db", str(db), "--plot", str(root / "c.png")], db).code == 0
    assert (root / "c.png").stat().st_size > 10_000 and (root / "c.svg").exists()
    for argv, words in (
        (["check", "chart", "--db", str(db), "--rig", "nope"], "no check runs of rig nope"),
        (["check", "chart", "--db", str(db), "--plot", str(root / "no" / "c.png")], "does not exist"),
        (["check", "--db", str(db), "--sim", "lab"], "--bat"),
        (["check", "--db", str(db), "--sim", "lab", "--bat", str(root / "missing.toml")], "missing.toml"),
    ):
        result = run_cli(argv, db)
        assert result.code == 2 and words in result.err and result.err.count("\n") == 1, result.err
        assert result.stray_runs == []


def _refusal(db: Path) -> str | None:
    from rig.quality.records import rig_quality
    from rig.store import Store

    with Store.open(db) as store:
        return rig_quality(store, "sim-lab").refusal()


def test_a_restart_starts_a_new_phase_i_for_the_chart_and_the_gate(lab: dict[str, object]) -> None:
    """After a corrective action, `rig check restart` (recorded) makes the next check runs a new phase
    I: the earlier sessions are neither charted nor judged, so their signals no longer block."""
    root = lab["root"]
    assert isinstance(root, Path)
    db = root / "restart" / "lab.db"
    db.parent.mkdir()
    shutil.copy(lab["db"], db)
    worn = str(root / "worn" / "lab.toml")
    check = ["check", "--bat", str(root / "ref.toml"), "--db", str(db), "--hits", str(HITS), "--json"]
    assert _json([*check, "--sim", worn])["signals"]  # the worn lot still: a new, open signal
    assert "not acknowledged" in (_refusal(db) or "")
    before = _chart_of(db)
    assert before["restart"] is None and before["sessions_before_restart"] == 0
    n = len(before["points"])
    assert run_cli(["check", "restart", "--db", str(db), "--who", "Q. Manager"], db).code == 2  # no --why
    done = run_cli(["check", "restart", "--db", str(db), "--who", "Q. Manager", "--why", "new lot"], db)
    assert done.code == 0, done.err
    assert _refusal(db) is None  # the gate judges the new phase I only: nothing yet
    after = _chart_of(db)
    assert after["points"] == [] and after["sessions_before_restart"] == n
    assert after["restart"]["who"] == "Q. Manager" and after["restart"]["why"] == "new lot"
    assert after["state"] == "building phase I (0 of 20 check runs since the restart)"
    new = _json([*check, "--sim", "lab"])
    assert new["state"] == "building phase I (1 of 20 check runs since the restart)"
    points = _chart_of(db)["points"]
    assert [p["session"] for p in points] == [new["run_id"]] and points[0]["phase"] == 1
    assert main(["verify", "--db", str(db)]) == 0


def _chart_of(db: Path) -> dict[str, object]:
    charts = _json(["check", "chart", "--db", str(db), "--json"])
    assert isinstance(charts, list) and len(charts) == 1
    return charts[0]


def test_sync_carries_acknowledgements_and_restarts_to_the_lab_store(lab: dict[str, object]) -> None:
    """rig sync copies CheckAcknowledged and CheckRestarted with the runs: the lab's store charts,
    gates and dates them as the rig's store does; a second sync adds nothing."""
    from rig.quality.records import acks, restarts
    from rig.store import Store

    root = lab["root"]
    assert isinstance(root, Path)
    rig_db, lab_db = root / "sync" / "rig.db", root / "sync" / "central.db"
    rig_db.parent.mkdir()
    shutil.copy(lab["db"], rig_db)
    if _refusal(rig_db):  # whatever the tests before left open: acknowledged here
        assert run_cli(["check", "ack", "--db", str(rig_db), "--who", "A", "--why", "seen"], rig_db).code == 0
    assert (
        run_cli(["check", "restart", "--db", str(rig_db), "--who", "B", "--why", "re-based"], rig_db).code
        == 0
    )
    assert _refusal(rig_db) is None
    assert _json(["sync", "--from", str(rig_db), "--to", str(lab_db), "--json"])["lab_entries_copied"] >= 2
    with Store.open(rig_db) as src, Store.open(lab_db) as dst:
        assert [a.as_dict() | {"seq": 0} for a in acks(src)] == [a.as_dict() | {"seq": 0} for a in acks(dst)]
        assert [(r.who, r.why, r.t_utc) for r in restarts(src)] == [
            (r.who, r.why, r.t_utc) for r in restarts(dst)
        ]
        assert len(acks(dst)) >= 1 and len(restarts(dst)) == 1
        entries = len(dst.entries())
    assert _refusal(lab_db) is None
    charted = [_chart_of(db) for db in (rig_db, lab_db)]
    for chart in charted:
        chart["restart"].pop("seq")  # each store's own lab chain numbers it
    assert charted[0] == charted[1]  # the same series, restart (when, who, why) and state
    again = _json(["sync", "--from", str(rig_db), "--to", str(lab_db), "--json"])
    assert again["lab_entries_copied"] == 0
    with Store.open(lab_db) as dst:
        assert len(dst.entries()) == entries
    assert main(["verify", "--db", str(lab_db)]) == 0
