"""Finding 6: the location of maximum performance must be bracketed, or the operator asked (recorded)."""

from __future__ import annotations

import textwrap
from pathlib import Path

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store
from tests.protocols.wire import check_fires

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
# The barrel's sweet spot 0.185 m (7.3 in) from the tip: beyond the default scan's 7.5 in edge
# once the bat's rising rigid-body trend is added, so the scan's highest mean is at its edge.
FAR_SWEET_SPOT = """
description = "sweet spot far from the tip"
seed = 1
[[effects]]
kind = "trampoline"
sweet_spot_from_tip_m = 0.185
width_m = 0.08
[[effects]]
kind = "recoil"
"""


class Operator:
    """Answers every prompt yes except those named in `no`; keeps what it was asked."""

    who = "test operator"

    def __init__(self, no: tuple[str, ...] = ()) -> None:
        self.no, self.asked = no, []

    def ask(self, prompt_id: str, text: str) -> bool:
        self.asked.append(prompt_id)
        return prompt_id not in self.no


def scan_means(entries: list) -> dict[float, float]:
    """Mean metric per location of the valid scan shots, straight from the shot entries."""
    where = {e.payload["index"]: e.payload for e in entries if e.kind == "ShotRequested"}
    acc: dict[float, list[float]] = {}
    for e in entries:
        if e.kind == "ShotMeasured" and where[e.payload["index"]]["purpose"] == "scan":
            acc.setdefault(where[e.payload["index"]]["location_in"], []).append(e.payload["metric"])
    return {k: sum(v) / len(v) for k, v in acc.items()}


def run(tmp_path: Path, scene: str, procedure: Procedure, operator: Operator) -> tuple[object, list, dict]:
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, procedure, bat, sim_config(scene, bat=bat), operator=operator)
        return out, store.entries(out.run_id), run_record(store, out.run_id)


def test_a_maximum_at_the_scan_edge_is_bracketed_by_extending_the_scan(tmp_path: Path) -> None:
    scene = tmp_path / "far.toml"
    scene.write_text(FAR_SWEET_SPOT)
    out, entries, rec = run(tmp_path, str(scene), Procedure.load("bbcor"), Operator())
    assert out.status == "finished"
    means = scan_means(entries)
    planned = [5.0, 5.5, 6.0, 6.5, 7.0, 7.5]
    assert max(planned, key=means.__getitem__) == 7.5  # within the procedure's scan: still rising
    extended = [e.payload["from_barrel_end_in"] for e in entries if e.kind == "ScanExtended"]
    assert extended and extended[0] == 8.0 and set(extended) <= {8.0, 8.5}
    best = max(means, key=means.__getitem__)
    assert best > 7.5  # the true maximum lies beyond the procedure's edge
    assert any(x < best and means[x] < means[best] for x in means)
    assert any(x > best and means[x] < means[best] for x in means)  # bracketed on both sides
    (chosen,) = [e.payload for e in entries if e.kind == "LocationChosen"]
    assert chosen["from_barrel_end_in"] == best and chosen["bracketed"] is True
    valid = [e.payload for e in entries if e.kind == "ShotRequested" and e.payload["purpose"] == "valid"]
    assert valid and all(p["location_in"] == best for p in valid)
    assert all(n == 1 for n in check_fires(entries).values())  # every extension shot at its place
    md = render(rec, "md")
    assert f"The scan was extended to {', '.join(f'{x:g}' for x in extended)} in" in md
    assert "is bracketed" in md


def test_an_unbracketed_edge_is_put_to_the_operator(tmp_path: Path) -> None:
    """The ideal bat's metric keeps rising towards the handle: extend by scan.extend_in, then ask."""
    operator = Operator()
    out, entries, rec = run(tmp_path, "ideal", Procedure.load("bbcor"), operator)
    assert out.status == "finished"
    assert [e.payload["from_barrel_end_in"] for e in entries if e.kind == "ScanExtended"] == [8.0, 8.5]
    assert operator.asked.count("edge-location") == 1
    (chosen,) = [e.payload for e in entries if e.kind == "LocationChosen"]
    assert chosen["from_barrel_end_in"] == 8.5 and chosen["bracketed"] is False
    assert chosen["accepted_by"] == "test operator"
    answered = [e.payload for e in entries if e.kind == "OperatorAnswered"]
    assert {"prompt_id": "edge-location", "answer": True, "who": "test operator"} in answered
    assert "NOT bracketed" in render(rec, "md")


def test_operator_declines_an_unbracketed_edge(tmp_path: Path) -> None:
    out, entries, _ = run(tmp_path, "ideal", Procedure.load("bbcor"), Operator(no=("edge-location",)))
    assert out.status == "interrupted" and "not bracketed" in out.reason
    assert not [e for e in entries if e.kind in ("LocationChosen", "RunFinished")]


def test_the_extension_stays_within_the_bat_and_the_stage(tmp_path: Path) -> None:
    """Near the handle the next step would put the stage below 100 mm: no extension, the operator is asked."""
    base = Procedure.load("bbcor")
    near_pivot = base.model_copy(
        update={
            "scan": base.scan.model_copy(update={"from_in": 22.0, "to_in": 23.0, "extend_in": 5.0}),
            "ring_check": False,
        }
    )
    operator = Operator()
    out, entries, _ = run(tmp_path, "ideal", near_pivot, operator)
    assert out.status == "finished"
    assert not [e for e in entries if e.kind == "ScanExtended"]  # 23.5 in would need the stage at 87 mm
    assert (33.0 - 6.0 - 23.5) * 25.4 < 100.0
    assert operator.asked == ["edge-location"]


def test_no_extension_allowed_asks_at_once(tmp_path: Path) -> None:
    base = Procedure.load("bbcor")
    proc = base.model_copy(update={"scan": base.scan.model_copy(update={"extend_in": 0.0})})
    operator = Operator()
    out, entries, _ = run(tmp_path, "ideal", proc, operator)
    assert out.status == "finished" and not [e for e in entries if e.kind == "ScanExtended"]
    assert "edge-location" in operator.asked


def test_old_procedure_records_still_load() -> None:
    """A procedure recorded before scan.extend_in existed validates (the default applies)."""
    text = textwrap.dedent("""
        {"name": "x", "standard": "bbcor", "edition": "e", "limit": 0.5,
         "scan": {"from_in": 5.0, "to_in": 7.5, "step_in": 0.5, "hits_per_location": 1}}
    """)
    assert Procedure.model_validate_json(text).scan.extend_in == 1.0


def test_a_single_location_scan_is_extended_on_both_sides(tmp_path: Path) -> None:
    base = Procedure.load("bbcor")
    one = base.model_copy(update={"scan": base.scan.model_copy(update={"from_in": 7.5, "to_in": 7.5})})
    operator = Operator()
    out, entries, _ = run(tmp_path, "ideal", one, operator)
    assert out.status == "finished"
    extended = [e.payload["from_barrel_end_in"] for e in entries if e.kind == "ScanExtended"]
    assert extended == [7.0, 8.0, 8.5]  # the tip side first, then towards the handle up to 1.0 in
    means = scan_means(entries)
    assert means[7.0] < means[7.5] < means[8.0] < means[8.5]  # the ideal bat: rising towards the handle
    assert operator.asked.count("edge-location") == 1
