"""Population datasets: the formats, errors naming file, line and field, the model overlay."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.core.errors import ConfigError
from rig.population import load_population
from rig.population.model import ReferenceBat, model_curves, predict_metrics


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
