"""Finding 10: every uncertainty input the certificate prints is an input of the budget."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify, history
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError
from rig.protocols import evaluate
from rig.protocols.procedure import Procedure
from rig.protocols.state import fold
from rig.session import sim_config
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Procedure, BatSpec, Any, RigConfig]:
    bat = BatSpec.load(SAMPLE_BAT)
    config = sim_config("drag", bat=bat)
    db = tmp_path_factory.mktemp("printed") / "r.db"
    with Store.open(db) as store:
        out = certify(store, Procedure.load("bbcor"), bat, config)
        state = fold(history(store, out.run_id))
    return Procedure.load("bbcor"), bat, state, config


def _with(config: RigConfig, table: str, field: str, value: float) -> RigConfig:
    data = config.model_dump(mode="json")
    data[table][field] = value
    return RigConfig.from_dict(data)


def _big_u(run: tuple, config: RigConfig) -> float:
    p, bat, state, _ = run
    return float(evaluate.verdict(p, bat, state, config).U)


PRINTED = [
    ("gates", "position_uncertainty_m", 0.002),
    ("air", "drag_coefficient_u", 0.2),
    ("air", "rebound_drag_coefficient_u", 0.3),
    ("air", "pressure_u_kpa", 20.0),
    ("air", "temperature_u_c", 5.0),
    ("air", "humidity_u_pct", 30.0),
]


@pytest.mark.parametrize(("table", "field", "value"), PRINTED)
def test_each_printed_input_changes_the_expanded_uncertainty(
    run: tuple, table: str, field: str, value: float
) -> None:
    base = _big_u(run, run[3])
    changed = _big_u(run, _with(run[3], table, field, value))
    assert changed > base, f"{table}.{field} = {value} left U at {base}"


@pytest.mark.parametrize(
    ("table", "field", "value"),
    [
        ("gates", "position_uncertainty_m", -1e-4),
        ("air", "drag_coefficient", 5.0),
        ("air", "pressure_kpa", 1e-300),
        ("pendulum", "gravity_m_s2", 1e300),
        ("pendulum", "scale_resolution_kg", -1.0),
    ],
)
def test_non_physical_inputs_are_refused(run: tuple, table: str, field: str, value: float) -> None:
    with pytest.raises(ConfigError) as err:
        _with(run[3], table, field, value)
    assert field in str(err.value) and "\n" not in str(err.value).strip()
