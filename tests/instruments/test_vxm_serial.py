"""The VXM stage and its swing sensor on serial ports (ptys in front of the twin), as a lab wires
them with USB adapters: the driver opens device paths with pyserial and moves, grips, times the
pendulum and reads the recoil exactly as over TCP."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.tomlfile import dump_toml
from rig.drivers.registry import DriverContext
from rig.drivers.vxm.clamp import VxmClamp
from rig.drivers.vxm.stage_codec import LEAD_MM_PER_STEP
from rig.protocols.procedure import Procedure
from rig.session import scene_with_bat
from rig.simulators.instruments.serve import rig_config, start_twins
from rig.simulators.instruments.vxm_stage import VxmStageTwin
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")


@pytest.fixture
def served() -> Iterator[tuple[SimWorld, VxmStageTwin]]:
    world = SimWorld(Scene.load("lab"))
    twin = VxmStageTwin(world, serial=True)
    twin.start()
    yield world, twin
    twin.close()


def test_the_clamp_on_two_serial_ports_moves_grips_and_times_the_pendulum(
    served: tuple[SimWorld, VxmStageTwin],
) -> None:
    world, twin = served
    table = twin.device_table()
    assert table["address"].startswith("/dev/") and table["options"]["sensor"].startswith("/dev/")
    traffic: list = []
    context = DriverContext(
        kind="clamp",
        name="clamp",
        address=table["address"],
        options=table["options"],
        on_traffic=traffic.append,
    )
    clamp = VxmClamp.from_context(context)
    try:
        for target in (612.3, 455.55):
            clamp.move_to(target)
            assert abs(world.clamp.position_mm() - target) <= LEAD_MM_PER_STEP
        clamp.clamp()
        assert world.clamp.locked
        period = clamp.measure_period(10)
        est = clamp.last_period
        assert est is not None and abs(period.period_s - world.swing_period()) <= 3 * est.u_s
        assert clamp.identify().model == "VXM-SIM + SWS-SIM"
    finally:
        clamp.close()
    sent = b"".join(r.data for r in traffic if r.direction == "tx")
    assert sent.count(b",R") == 2 and b"SWING" in sent  # the stage's programs and the sensor's commands


def test_a_certification_with_the_plc_and_the_clamp_on_serial_ports(tmp_path: Path) -> None:
    """`rig sim serve --instruments --serial`: the PLC on Modbus RTU and the stage and sensor on
    ptys (the counter stays on LAN); a bat certifies through them, every launch recorded once."""
    world = SimWorld(scene_with_bat(Scene.load("ideal"), BAT))
    twins = start_twins(world, serial=True)
    try:
        table = rig_config(world.scene, twins)
        devices = table["devices"]
        assert (
            devices["cannon"]["address"].startswith("/dev/")
            and devices["cannon"]["options"]["transport"] == "rtu"
        )
        assert devices["clamp"]["address"].startswith("/dev/") and devices["gates"]["address"].startswith(
            "TCPIP"
        )
        path = tmp_path / "rig.toml"
        path.write_text(dump_toml(table), encoding="utf-8")
        p = Procedure.load("bbcor")
        procedure = p.model_copy(update={"hits": p.hits.model_copy(update={"valid_hits": 2})})
        with Store.open(tmp_path / "records.db") as store:
            out = certify(store, procedure, BAT, RigConfig.load(path))
            fired = [e for e in store.entries(out.run_id) if e.kind == "ShotFired"]
    finally:
        for twin in twins:
            twin.close()
    assert out.status == "finished", out.reason
    assert len(fired) == len(world.shots) >= 2
