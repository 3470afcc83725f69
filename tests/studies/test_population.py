"""The population study: binning against a hand computation, the synthetic sample and its shape."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.core.errors import ParameterError
from rig.population import load_population, write_population_csv
from studies.population.binning import bin_by_hoop
from studies.population.study import run_study
from studies.population.synthetic import HEADER, synthetic_population

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
