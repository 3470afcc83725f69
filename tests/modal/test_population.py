"""The population study: dataset formats, binning against a hand computation, the model overlay."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.core.errors import ConfigError, ParameterError
from rig.population import bin_by_hoop, load_population, run_study, write_population_csv
from rig.population.model import ReferenceBat, model_curves, predict_metrics
from rig.population.synthetic import HEADER, synthetic_population

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "protocols" / "examples" / "population.csv"


def test_binning_by_hand() -> None:
    hoops = [1400.0, 1424.9, 1425.0, 1449.0, 1476.0, 1500.0, 1580.0, 1590.0]
    values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, None]
    bins = bin_by_hoop(hoops, values)
    # [1375, 1425): 1, 2 | [1425, 1475): 3, 4 | [1475, 1525): 5, 6 | 1550 empty
    # [1575, 1625): 7 (the None is skipped)
    assert [(b.center_hz, b.n, b.mean) for b in bins] == [
        (1400.0, 2, 1.5),
        (1450.0, 2, 3.5),
        (1500.0, 2, 5.5),
        (1600.0, 1, 7.0),
    ]
    assert bins[0].std == pytest.approx(0.5**0.5) and bins[-1].std is None
    assert (bins[1].lo_hz, bins[1].hi_hz) == (1425.0, 1475.0)
    # a wider averaging window overlaps its neighbours: 1450 +- 50 takes 1400 .. 1476
    wide = {b.center_hz: b for b in bin_by_hoop(hoops, values, 50.0, 50.0)}
    assert wide[1450.0].n == 5 and wide[1450.0].mean == pytest.approx(3.0)
    assert bin_by_hoop([], []) == []
    with pytest.raises(ParameterError):
        bin_by_hoop([1.0], [1.0, 2.0])


def test_sample_population_is_labelled_synthetic_and_reproducible(tmp_path: Path) -> None:
    text = SAMPLE.read_text()
    assert text.startswith("# SYNTHETIC SAMPLE POPULATION")
    bats = load_population(SAMPLE)
    assert len(bats) == 48 and all(b.synthetic for b in bats)
    again = write_population_csv(synthetic_population(), tmp_path / "p.csv", HEADER)
    assert again.read_text() == text  # the shipped file is what the generator makes


def test_sample_population_has_the_papers_shape() -> None:
    study = run_study(load_population(SAMPLE))
    mats = study.materials()
    assert mats["composite"]["hoop_span_hz"] > 2 * mats["aluminium"]["hoop_span_hz"]  # Fig. 5
    hoops = [b.hoop_hz for b in study.bats]
    assert min(hoops) >= 1400 and max(hoops) <= 3000
    for name in ("besr", "bbs", "bbcor"):  # Fig. 6: performance falls as the hoop frequency rises
        t = study.trend[name]
        assert t["slope_per_khz"] < 0 and t["model_slope_per_khz"] < 0 and t["r"] < -0.5
        assert t["slope_per_khz"] == pytest.approx(t["model_slope_per_khz"], rel=0.3)
        assert sum(b.n for b in study.bins[name]) == 48


def test_model_curve_is_predict_bat_and_compute_metrics() -> None:
    ref = ReferenceBat.at(33.0, 0.19)
    curve = model_curves([1500.0, 2500.0], ref)
    one = predict_metrics(2500.0, ref)
    assert curve["bbcor"][1] == one["bbcor"] and curve["besr"][1] == pytest.approx(one["e_a"] + 0.5)
    assert curve["bbcor"][0] > curve["bbcor"][1]


def test_csv_and_toml_formats(tmp_path: Path) -> None:
    csv = tmp_path / "p.csv"
    csv.write_text("# a comment\nbat_id,barrel,hoop_hz,bbcor\nA1,aluminium,1800,0.5\nC1,composite,2400,\n")
    a, c = load_population(csv)
    assert (a.bat_id, a.hoop_hz, a.bbcor, c.bbcor, a.bending_hz) == ("A1", 1800.0, 0.5, None, None)
    toml = tmp_path / "p.toml"
    toml.write_text('[[bat]]\nbat_id = "A1"\nbarrel = "aluminium"\nhoop_hz = 1800.0\nbending_hz = 170.0\n')
    (t,) = load_population(toml)
    assert t.bending_hz == 170.0


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("bat_id,barrel\nA1,aluminium\n", "missing column(s) hoop_hz"),
        ("bat_id,barrel,hoop_hz,colour\nA1,aluminium,1800,red\n", "unknown column(s) colour"),
        ("bat_id,barrel,hoop_hz\nA1,steel,1800\n", "line 2: barrel"),
        ("bat_id,barrel,hoop_hz\nA1,aluminium,-5\n", "line 2: hoop_hz"),
        ("bat_id,barrel,hoop_hz\nA1,aluminium\n", "2 cells, the header has 3"),
        ("bat_id,barrel,hoop_hz\nA1,aluminium,1800\nA1,composite,1900\n", "bat A1 appears twice"),
    ],
)
def test_population_errors_name_file_line_and_field(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "p.csv"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_population(path)
    assert needle in str(err.value) and "p.csv" in str(err.value)
