"""USA Softball BBS: the edition chosen by the procedure's date, certified end to end on the simulated
rig, and each shot's metric recomputed from the raw record with formulas written here."""

from __future__ import annotations

import contextlib
import io
import json
from datetime import date
from pathlib import Path

import pytest

from rig.cli import main
from rig.core.errors import ConfigError
from rig.protocols.procedure import Procedure

ROOT = Path(__file__).resolve().parents[2]
SOFTBALL_BAT = ROOT / "protocols" / "examples" / "softball-bat.toml"
MPH = 0.44704
IN = 0.0254
# the editions as written in protocols/softball-bbs.toml's sources: (from, cannon, pitch, bat) in mph
EDITIONS = {"2004": (date(2004, 1, 1), 110.0, 25.0, 85.0), "2012": (date(2012, 10, 1), 105.0, 25.0, 80.0)}


def _cli(*args: str) -> tuple[int, str]:
    with contextlib.redirect_stdout(io.StringIO()) as out:
        code = main(list(args))
    return code, out.getvalue()


def _bbs_mph_model(e_a: float, q_m: float, length_m: float, pitch_mph: float, bat_mph: float) -> float:
    """BBS (m/s): pitch e_A + bat(Q) (1 + e_A), the bat turning about 6 in from the knob (the rig's
    pivot too) with `bat_mph` at 6 in from the barrel end."""
    v_bat = bat_mph * MPH * q_m / (length_m - 12 * IN)
    return pitch_mph * MPH * e_a + v_bat * (1 + e_a)


def _procedure(tmp_path: Path, day: str, extra: str = "") -> Path:
    text = (ROOT / "protocols" / "softball-bbs.toml").read_text(encoding="utf-8")
    text = text.replace("edition_date = 2012-10-01", f"edition_date = {day}") + extra
    path = tmp_path / f"softball-{day}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("day", "key"),
    [("2004-06-01", "2004"), ("2012-09-30", "2004"), ("2012-10-01", "2012"), ("2020-01-01", "2012")],
)
def test_the_edition_date_chooses_the_cannon_speed_and_the_constants(
    tmp_path: Path, day: str, key: str
) -> None:
    p = Procedure.load(_procedure(tmp_path, day))
    assert p.standard == f"usas_bbs_{key}" and p.edition_date == date.fromisoformat(day)
    assert p.target_speed_m_s == pytest.approx(EDITIONS[key][1] * MPH, abs=1e-4)
    assert p.limit == pytest.approx(98 * MPH, abs=0.005) and p.ball.ball_class == "44/375"
    assert p.metric.value(0.2, _terms()) == pytest.approx(
        EDITIONS[key][2] * MPH * 0.2 + 30.0 * EDITIONS[key][3] / 66.0 * 1.2, rel=1e-12
    )


def _terms():  # type: ignore[no-untyped-def]
    from rig.measure.registry import MetricTerms

    return MetricTerms(k=0.2, v_bat=30.0, v_pitch=31.3)


def test_a_date_before_the_first_edition_or_a_wrong_speed_is_refused_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no USA Softball BBS edition in force on 2003-12-31") as caught:
        Procedure.load(_procedure(tmp_path, "2003-12-31"))
    assert "\n" not in str(caught.value)
    text = _procedure(tmp_path, "2012-10-01").read_text(encoding="utf-8")
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(text.replace("speed_tolerance_m_s", "target_speed_m_s = 49.17\nspeed_tolerance_m_s"))
    with pytest.raises(ConfigError, match=r"is not the usas_bbs_2012 test speed 46\.94"):
        Procedure.load(wrong)
    undated = tmp_path / "undated.toml"
    undated.write_text(text.replace("edition_date = 2012-10-01", ""))
    with pytest.raises(ConfigError, match="needs the procedure's edition_date"):
        Procedure.load(undated)
    bad_class = tmp_path / "class.toml"
    bad_class.write_text(text.replace('ball_class = "44/375"', 'ball_class = "hot"'))
    with pytest.raises(ConfigError, match=r"procedure\.ball\.ball_class"):
        Procedure.load(bad_class)


def _quiet_softball_scene(folder: Path) -> Path:
    """The softball scene with every effect off but its trampoline barrel: no drag, no noise."""
    text = (ROOT / "simulators" / "scenes" / "softball.toml").read_text(encoding="utf-8")
    for kind in ("speed_scatter", "gate_timing", "drag", "recoil", "ball_wear", "environment"):
        text = text.replace(f'kind = "{kind}"', f'kind = "{kind}"\nenabled = false')
    path = folder / "quiet-softball.toml"
    path.write_text(text.replace("spread_bbcor = 0.005", "spread_bbcor = 0.0"), encoding="utf-8")
    return path


def _truth_bbs(record: dict, scene: str | Path) -> tuple[float, float]:  # type: ignore[type-arg]
    """The simulated bat's true BBS (2012 constants, the formula above) at its scanned maximum: e_A of a
    new nominal 44/375 ball at the cannon speed from the scene, no measurement chain; and where."""
    from rig.core.bat import BatSpec
    from rig.session import scene_with_bat
    from rig.simulators.scene import Scene
    from rig.simulators.truth import true_metric

    _, cannon, pitch, bat = EDITIONS["2012"]
    sim = scene_with_bat(Scene.load(scene).with_ball_class("44/375"), BatSpec.load(SOFTBALL_BAT))
    locations = tuple(5.0 + 0.5 * i for i in range(6))
    e_a = true_metric(sim, locations, "e_a", cannon * MPH).by_location
    length = record["bat"]["length_in"] * IN
    bbs = {x: _bbs_mph_model(e, length - 6 * IN - x * IN, length, pitch, bat) for x, e in e_a.items()}
    best = max(bbs, key=lambda x: bbs[x])
    return bbs[best], best


def _certify(tmp_path: Path, scene: str) -> tuple[int, dict, str]:  # type: ignore[type-arg]
    db = str(tmp_path / "softball.db")
    where = str(_quiet_softball_scene(tmp_path)) if scene == "quiet" else scene
    code, _ = _cli(
        "certify", "--procedure", "softball-bbs", "--bat", str(SOFTBALL_BAT), "--sim", where, "--db", db
    )
    _, text = _cli("report", "last", "--db", db, "--format", "json")
    _, md = _cli("report", "last", "--db", db, "--format", "md")
    return code, json.loads(text), md


def test_softball_bbs_certifies_on_the_ideal_rig_and_recomputes_from_the_gate_ticks(tmp_path: Path) -> None:
    code, record, md = _certify(tmp_path, "quiet")
    assert record["status"] == "finished" and code in (0, 1)
    length = record["bat"]["length_in"] * IN
    _, cannon, pitch, bat = EDITIONS["2012"]
    shots = [s for s in record["shots"] if s.get("metric") is not None]
    assert len(shots) >= 6
    for s in shots:
        raw = s["raw"]
        ticks = {(c["gate"], i < 3): c["tick"] for i, c in enumerate(raw["crossings"])}
        tick_s = raw["gate_config"]["tick_ns"] * 1e-9
        x = raw["gate_positions_m"]
        v_in = (x[1] - x[2]) / ((ticks[(3, True)] - ticks[(2, True)]) * tick_s)  # nearest pair, inbound
        v_out = (x[1] - x[2]) / ((ticks[(2, False)] - ticks[(3, False)]) * tick_s)
        assert abs(v_in - cannon * MPH) < 0.447 * 1.5
        expected = _bbs_mph_model(v_out / v_in, raw["impact_from_pivot_m"], length, pitch, bat)
        assert s["metric"] == s["metrics"]["usas_bbs_2012"] == pytest.approx(expected, rel=1e-9)
    verdict = record["verdict"]
    assert verdict["metric"] == "usas_bbs_2012" and verdict["limit"] == 43.81
    assert verdict["mean"] == pytest.approx(sum(verdict["hits"]) / verdict["n_hits"], rel=1e-12)
    assert ("PASS" if verdict["mean"] + verdict["U"] <= 43.81 else "FAIL") == verdict["verdict"]
    assert "| ball class | 44/375 |" in md and "| edition in force from | 2012-10-01 |" in md
    # the simulated lab fired 44/375 softballs (recorded with the rig), and the certified value is
    # the simulated bat's: exact speeds in a quiet scene, so within U of the truth
    assert record["rig"]["name"].endswith("softballs 44/375)")
    truth, where = _truth_bbs(record, tmp_path / "quiet-softball.toml")
    assert verdict["location_in"] == where and abs(verdict["mean"] - truth) <= verdict["U"]


def test_softball_bbs_certifies_on_the_lab_with_its_certificate(tmp_path: Path) -> None:
    code, record, md = _certify(tmp_path, "softball")
    assert record["status"] == "finished" and code == (0 if record["verdict"]["verdict"] == "PASS" else 1)
    length = record["bat"]["length_in"] * IN
    _, _, pitch, bat = EDITIONS["2012"]
    for s in (s for s in record["shots"] if s.get("metric") is not None):
        e_a = s["rebound_at_impact_m_s"] / s["inbound_at_impact_m_s"]  # drag-corrected at the impact point
        q = s["raw"]["impact_from_pivot_m"]
        assert s["metric"] == pytest.approx(_bbs_mph_model(e_a, q, length, pitch, bat), rel=1e-9)
    truth, _ = _truth_bbs(record, "softball")
    assert abs(record["verdict"]["mean"] - truth) <= record["verdict"]["U"], (record["verdict"], truth)
    assert "BBS (USA Softball 2012)" in md and "| ball class | 44/375 |" in md
    assert "standard: usas_bbs_2012" in md and "against the limit 43.81 m/s" in md
