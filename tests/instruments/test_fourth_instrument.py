"""A fourth instrument class costs its own module and one registry line, nothing else: a driver and
a twin that no file of the project names are served by `rig sim serve --instruments --twin`, opened
by the session through the registry and certify a bat, recorded under their driver's name."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import pytest

from rig.certification import certify
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError
from rig.core.tomlfile import dump_toml
from rig.drivers import registry
from rig.drivers.scpi.counter import ScpiCounterGates
from rig.protocols.procedure import Procedure
from rig.session import scene_with_bat
from rig.simulators.instruments.scpi_counter import ScpiCounterTwin
from rig.simulators.instruments.serve import rig_config, start_twins, twin_drivers
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")
HERE = "tests.instruments.test_fourth_instrument"


class LabCounterGates(ScpiCounterGates):
    """The fourth class's driver (a counter of the SCPI family, as a lab's next one would start)."""


class LabCounterTwin(ScpiCounterTwin):
    """Its twin: serves the gates under the new driver's name."""

    DRIVER: ClassVar[str] = "lab-counter"


@pytest.fixture
def fourth(monkeypatch: pytest.MonkeyPatch) -> str:
    """The one registry line the new class costs."""
    line = registry.Builtin({"gates": f"{HERE}:LabCounterGates.from_context"}, twin=f"{HERE}:LabCounterTwin")
    monkeypatch.setitem(registry.BUILTIN, "lab-counter", line)  # type: ignore[attr-defined]
    return "lab-counter"


def test_every_builtin_twin_serves_its_own_driver_and_kind() -> None:
    from rig.simulators.instruments.serve import twin_class

    with_twins = {name: entry for name, entry in registry.BUILTIN.items() if entry.twin}
    assert set(with_twins) == {"scpi-counter", "vxm-stage", "modbus-cannon", "scpi-compression"}
    for name, entry in with_twins.items():
        cls = twin_class(name)
        assert name == cls.DRIVER and cls.KIND in entry.factories
    assert twin_drivers() == {"cannon": "modbus-cannon", "gates": "scpi-counter", "clamp": "vxm-stage"}


@pytest.mark.parametrize(
    ("chosen", "said"),
    [
        ({"gates": "vxm-stage"}, "no twin of driver 'vxm-stage' for the gates (twins: scpi-counter)"),
        ({"gates": "rig-line"}, "no twin of driver 'rig-line' for the gates"),
        ({"door": "scpi-counter"}, "no device kind 'door'"),
    ],
)
def test_a_twin_that_cannot_serve_the_kind_is_refused_in_one_line(chosen: dict[str, str], said: str) -> None:
    with pytest.raises(ConfigError) as caught:
        twin_drivers(chosen)
    assert said in str(caught.value) and "\n" not in str(caught.value)


def test_a_fourth_instrument_class_certifies_through_its_twin(fourth: str, tmp_path: Path) -> None:
    world = SimWorld(scene_with_bat(Scene.load("ideal"), BAT))
    twins = start_twins(world, chosen={"gates": fourth})
    try:
        table = rig_config(world.scene, twins)
        assert table["devices"]["gates"]["driver"] == fourth
        path = tmp_path / "rig.toml"
        path.write_text(dump_toml(table), encoding="utf-8")
        config = RigConfig.load(path)
        p = Procedure.load("bbcor")
        procedure = p.model_copy(update={"hits": p.hits.model_copy(update={"valid_hits": 2})})
        with Store.open(tmp_path / "records.db") as store:
            out = certify(store, procedure, BAT, config)
            entries = store.entries(out.run_id)
    finally:
        for twin in twins:
            twin.close()
    assert out.status == "finished"
    (identified,) = [e for e in entries if e.kind == ev.InstrumentsIdentified.kind]
    gates = identified.payload["devices"]["gates"]
    assert gates["driver"] == fourth and gates["simulated"] is True
    assert "53230A-SIM" in str(gates)  # what the twin said it is, read through the new driver
    fired = [e for e in entries if e.kind == ev.ShotFired.kind]
    assert len(fired) == len(world.shots) >= 2


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--twin", "gates=scpi-counter"], "--twin goes with --instruments"),
        (["--instruments", "--twin", "gates"], "'gates' is not KIND=DRIVER"),
        (["--instruments", "--twin", "gates=rig-line"], "no twin of driver 'rig-line' for the gates"),
        (["--instruments", "--base-port", "65533"], "the twins need 4 ports from it, past 65535"),
    ],
)
def test_the_serve_command_refuses_a_twin_it_cannot_serve(argv: list[str], said: str) -> None:
    from tests.unit.clirun import run_cli

    result = run_cli(["sim", "serve", "--scene", "ideal", *argv])
    assert result.code not in (0, None)
    assert said in result.err, result.err
