"""The vxm-stage clamp: codecs, the driver against its twin over real TCP, a full simulated
certification with the clamp on the twin and cannon + gates on sim:// of the same world, and faults."""

from __future__ import annotations

import math
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.config import Devices, DeviceSpec, RigConfig
from rig.core.devices import FireAware
from rig.core.errors import DeviceGone, DeviceTimeout, GarbledReply, NotSent
from rig.drivers.registry import DriverContext
from rig.drivers.vxm import stage_codec, swing_codec
from rig.drivers.vxm.clamp import VxmClamp
from rig.drivers.vxm.stage_codec import Done, Junk, Line, StageGeometry, Status
from rig.measure.moi import moi_from_period
from rig.protocols.executor import LiveRig
from rig.protocols.procedure import Procedure
from rig.session import RigSession, sim_config
from rig.simulators.instruments.vxm_stage import VxmStageTwin
from rig.simulators.scene import Scene
from rig.simulators.urlhandler import get_world
from rig.simulators.world import SimWorld
from rig.store import Store
from tests.instruments.attempts import write_until_one_fails

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
LEAD = stage_codec.LEAD_MM_PER_STEP


# -- codecs ---------------------------------------------------------------------------------
def test_a_program_clears_sets_speed_indexes_and_runs() -> None:
    assert stage_codec.program([100, 250], motor=1, speed_sps=2000) == b"C,S1M2000,IA1M100,IA1M250,R"


def test_every_target_is_approached_from_below() -> None:
    g = StageGeometry(LEAD, 0.0, 0.1)
    assert g.legs(100, 500) == [500]
    assert g.legs(500, 100) == [100 - math.ceil(0.1 / LEAD), 100]
    assert g.mm_for(g.steps_for(500.0)) == pytest.approx(500.0, abs=LEAD / 2)


def test_the_host_decoder_tells_done_status_lines_and_junk() -> None:
    items = stage_codec.HostDecoder().feed(b"R^+0001234\rVXM-1 2.1\r\xff")
    assert items == [Status("R"), Done(), Line("+0001234"), Line("VXM-1 2.1"), Junk(b"\xff")]
    assert stage_codec.parse_position("+0001234") == 1234
    with pytest.raises(ValueError, match="not a position"):
        stage_codec.parse_position("12a")


def test_the_device_tokenizer_splits_a_program() -> None:
    tokens = stage_codec.DeviceTokenizer().feed(b"F,C,S1M2000,IA1M-50,IA1M-0,R")
    assert tokens == ["F", "C", "S1M2000", "IA1M-50", "IA1M-0", "R"]
    assert stage_codec.parse_program_token("IA1M-50") == stage_codec.Index(1, -50, True)
    with pytest.raises(ValueError, match="unknown command"):
        stage_codec.parse_program_token("Z9")


def test_sensor_lines_and_samples() -> None:
    assert swing_codec.parse_command("CAP 10 200") == swing_codec.Command("CAP", (10.0, 200.0))
    with pytest.raises(ValueError, match="CAP takes 2 values"):
        swing_codec.parse_command("CAP 10")
    assert swing_codec.parse_sample(swing_codec.encode_sample(1.5, -2.25)) == (1.5, -2.25)
    assert swing_codec.LineSplitter().feed(b"OK\r\n\xffbad\r\n") == ["OK", b"\xffbad"]


# -- the driver against the twin over TCP -----------------------------------------------------
@pytest.fixture
def world() -> SimWorld:
    return SimWorld(Scene.load("lab"))


def _driver(twin: VxmStageTwin, **options: object) -> tuple[VxmClamp, list]:
    url = twin.start()
    table = twin.device_table()
    traffic: list = []
    ctx = DriverContext(
        kind="clamp",
        name="clamp",
        address=url,
        options={**table["options"], **options},
        on_traffic=traffic.append,
    )
    return VxmClamp.from_context(ctx), traffic


@pytest.fixture
def twin(world: SimWorld) -> Iterator[VxmStageTwin]:
    t = VxmStageTwin(world)
    yield t
    t.close()


def test_moves_land_on_the_worlds_carriage_within_a_step_from_either_side(
    world: SimWorld, twin: VxmStageTwin
) -> None:
    clamp, traffic = _driver(twin)
    try:
        for target in (612.3, 455.55, 700.0, 300.01):
            before = world.clock
            clamp.move_to(target)
            assert abs(world.clamp.position_mm() - target) <= LEAD  # the world's impact point
            assert world.clock > before  # the move took virtual time
            status = clamp.status()
            assert abs(status.position_mm - target) <= LEAD and not status.moving
        assert b"".join(r.data for r in traffic if r.direction == "tx").count(b",R") == 4
    finally:
        clamp.close()


def test_without_the_backlash_allowance_a_move_down_is_off_by_the_play(world: SimWorld) -> None:
    twin = VxmStageTwin(world, backlash_mm=0.05)
    clamp, _ = _driver(twin, backlash_mm=0.0)
    try:
        clamp.move_to(450.0)  # from 500 mm: a move down, approached from above
        assert world.clamp.position_mm() - 450.0 == pytest.approx(0.05, abs=LEAD)
    finally:
        clamp.close()
        twin.close()


def test_a_target_outside_the_stage_is_refused_unsent(twin: VxmStageTwin) -> None:
    clamp, traffic = _driver(twin)
    try:
        sent = len(traffic)
        with pytest.raises(NotSent, match="950 mm is outside the stage's 100-900 mm"):
            clamp.move_to(950.0)
        assert not any(b",R" in r.data for r in traffic[sent:])
    finally:
        clamp.close()


def test_grip_period_and_identity(world: SimWorld, twin: VxmStageTwin) -> None:
    clamp, _ = _driver(twin)
    try:
        clamp.clamp()
        assert world.clamp.locked and world.interlocks().clamp
        period = clamp.measure_period(10)
        truth = world.swing_period()
        est = clamp.last_period
        assert est is not None and 0 < est.u_s < 1e-3
        assert abs(period.period_s - truth) <= 3 * est.u_s
        assert period.amplitude_deg == pytest.approx(world.scene.rig.swing_amplitude_deg, abs=0.05)
        ident = clamp.identify()
        assert ident.model == "VXM-SIM + SWS-SIM" and "sim-1" in ident.firmware
        clamp.release()
        assert not world.clamp.locked
    finally:
        clamp.close()


def test_recoil_is_the_worlds_within_its_uncertainty(world: SimWorld, twin: VxmStageTwin) -> None:
    clamp, _ = _driver(twin)
    try:
        assert clamp.next_recoil(0.05) is None  # nothing fired yet
        omega = 31.4159
        with world.lock:
            world.clamp.report_recoil(omega, world.clock + 0.02, 1)
        recoil = clamp.next_recoil(1.0)
        assert recoil is not None and clamp.last_recoil is not None
        assert abs(recoil.omega_rad_s - omega) <= 3 * clamp.last_recoil.u_rad_s + 1e-6
        assert clamp.next_recoil(0.05) is None  # the same capture is not given twice
    finally:
        clamp.close()


def test_a_capture_the_pendulums_swing_triggered_is_never_an_impacts_recoil() -> None:
    """The armed sensor also triggers on the MOI swing (a 30 degree release: its peak speed is well
    above the threshold and resolved): the next recoil asked for, with no impact, is none, and a
    later impact gives its own speed."""
    lab = Scene.load("lab")
    world = SimWorld(lab.model_copy(update={"rig": lab.rig.model_copy(update={"swing_amplitude_deg": 30.0})}))
    twin = VxmStageTwin(world)
    clamp, _ = _driver(twin, trigger_deg_s=30.0)
    try:
        clamp.clamp()
        period = world.swing_period()
        swing_peak = math.radians(world.scene.rig.swing_amplitude_deg) * 2 * math.pi / period
        assert math.degrees(swing_peak) > 60.0  # the swing does trigger the sensor
        clamp.measure_period(3)
        assert twin._trig is not None  # it triggered
        assert clamp.next_recoil(0.05) is None  # not taken for an impact's recoil
        omega = 31.4159
        with world.lock:
            world.clamp.report_recoil(omega, world.clock + 0.02, 1)
        recoil = clamp.next_recoil(1.0)
        assert recoil is not None and abs(recoil.omega_rad_s - omega) <= 0.01 * omega
    finally:
        clamp.close()
        twin.close()


# -- faults ---------------------------------------------------------------------------------
def test_a_stage_that_does_not_acknowledge_is_one_line(world: SimWorld) -> None:
    twin = VxmStageTwin(world, stage_silent_after=1)
    clamp, _ = _driver(twin)
    clamp.stage_timeout_s = 1.0
    try:
        clamp.move_to(520.0)
        with pytest.raises(DeviceTimeout) as caught:
            clamp.move_to(540.0)
        assert "did not acknowledge the move to 540 mm (no '^') within 1 s" in str(caught.value)
        assert "\n" not in str(caught.value)
    finally:
        clamp.close()
        twin.close()


def test_a_dropped_stage_connection_is_one_line(world: SimWorld) -> None:
    twin = VxmStageTwin(world, drop_after=0)
    clamp, _ = _driver(twin)
    try:
        with pytest.raises((DeviceGone, DeviceTimeout)) as caught:
            clamp.move_to(520.0)
        assert "\n" not in str(caught.value) and "stage" in str(caught.value)
    finally:
        clamp.close()
        twin.close()


def test_a_silent_sensor_after_a_shot_is_a_lost_device_not_a_hang(world: SimWorld) -> None:
    twin = VxmStageTwin(world, sensor_silent_after=3)  # RES?, ARM, TRIG? at open
    clamp, _ = _driver(twin)
    try:
        with pytest.raises(DeviceGone, match=r"swing sensor went silent: .*TRIG"):
            clamp.next_recoil(0.05)
    finally:
        clamp.close()
        twin.close()


def test_a_write_to_a_closed_peer_leaves_no_tx_record_of_the_failed_bytes(twin: VxmStageTwin) -> None:
    """The stage's connection closes: the first write after it may still reach the socket, a later
    one fails (broken pipe, DeviceGone). Bytes written are in the record; those whose write failed
    never left and are not."""
    clamp, traffic = _driver(twin)
    try:
        twin._servers[0].close()  # the stage hangs up
        time.sleep(0.05)
        found = write_until_one_fails(lambda i: clamp._stage.send(f"V{i},".encode()))
    finally:
        clamp.close()
    assert found is not None, "no write to the closed peer failed"
    failed, exc = found
    assert "stage: write failed" in str(exc)
    sent = [r.data for r in traffic if r.direction == "tx"]
    assert f"V{failed},".encode() not in sent
    assert all(f"V{i},".encode() in sent for i in range(failed))


def test_a_garbled_sensor_line_is_one_line(world: SimWorld, twin: VxmStageTwin) -> None:
    clamp, _ = _driver(twin)
    try:
        clamp._lines.clear()
        clamp._splitter.feed(b"")
        clamp._lines.append(b"\xfe\xff")
        with pytest.raises(GarbledReply, match="garbled line"):
            clamp._line(0.0, "LOCK?")
    finally:
        clamp.close()


# -- a whole certification -------------------------------------------------------------------
def _twin_config(bat: BatSpec, **faults: object) -> tuple[RigConfig, SimWorld, VxmStageTwin]:
    rig = f"vxm-{uuid.uuid4().hex[:8]}"
    config = sim_config("lab", rig_name=rig, bat=bat)
    world = get_world(rig)
    twin = VxmStageTwin(world, **faults)  # type: ignore[arg-type]
    twin.start()
    devices = Devices(clamp=DeviceSpec(**twin.device_table()))
    return config.model_copy(update={"devices": devices}), world, twin


def test_a_certification_with_the_clamp_on_the_twin(tmp_path: Path) -> None:
    bat = BatSpec.load(SAMPLE_BAT)
    config, world, twin = _twin_config(bat)
    try:
        with Store.open(tmp_path / "r.db") as store:
            out = certify(store, Procedure.load("bbcor"), bat, config)
            entries = store.entries(out.run_id)
    finally:
        twin.close()
    assert out.status == "finished" and out.verdict is not None
    fired = [e for e in entries if e.kind == "ShotFired"]
    assert len(fired) == len(world.shots) == world.attempts  # nothing fired twice
    located = [e.payload["impact_from_pivot_m"] for e in entries if e.kind == "LocationSet"]
    for shot in world.shots:
        assert min(abs(shot.impact_from_pivot_m - q) for q in located) <= LEAD / 1000.0
    moi = next(e.payload for e in entries if e.kind == "MoiMeasured")
    true_moi = world.scene.bat.moi_kgm2
    assert abs(moi["moi_kgm2"] - true_moi) <= 2 * moi["u_kgm2"]
    # the host's period alone, without the budget's other inputs, is much closer than that
    bat_t, rig_t = world.scene.bat, world.scene.rig
    lever = bat_t.balance_point_m - rig_t.pivot_from_knob_m
    t_true = world.swing_period()
    direct = moi_from_period(bat_t.mass_kg, 9.80665, lever, t_true, math.radians(rig_t.swing_amplitude_deg))
    assert direct == pytest.approx(true_moi, rel=1e-9)  # the closed form the pendulum inverts
    assert moi.get("period_s", moi.get("extra", {}).get("period_s")) == pytest.approx(t_true, rel=2e-5)
    # the host fit's own u of each period is recorded and budgeted: T_host holds what the host u of
    # the mean goes beyond the repeats' scatter, so T_scatter and T_host combine to the larger of the
    # two (never less than the host's u), and the truth lies within it: |T - T_true| <= 3 u_T
    host_u = moi["periods_host_u_s"]
    rows = {c["input"]: c["u"] for c in moi["contributions"]}
    assert len(host_u) == len(moi["periods_s"]) and rows["T_host"] >= 0.0
    u_host = math.sqrt(sum(u * u for u in host_u)) / len(host_u)
    u_period = math.hypot(rows["T_scatter"], rows["T_host"])
    assert u_period == pytest.approx(max(rows["T_scatter"], u_host), rel=1e-9)
    assert abs(moi["period_s"] - t_true) <= 3 * u_period


def test_a_touch_before_fire_is_never_a_shots_recoil() -> None:
    """Through the twin and the executor's fire path (LiveRig.fire -> fire_shot): the bat is touched
    after the stage moved and before FIRE, and the sensor captures it. The clamp is FireAware, so
    the capture is set aside before FIRE: a ball that misses the bat reports no recoil (not the
    touch), and a ball that hits reports its own."""
    bat = BatSpec.load(SAMPLE_BAT)
    config, world, twin = _twin_config(bat)
    tip_m = world.scene.bat.length_m - world.scene.rig.pivot_from_knob_m
    aim = float(config.aim.speed_m_s[len(config.aim.speed_m_s) // 2])
    try:
        with RigSession.open(config) as session:
            assert isinstance(session.clamp, FireAware)
            live = LiveRig(session.cannon, session.gates, session.clamp)
            miss_q = 0.8
            assert miss_q > tip_m  # the stage puts the impact point past the bat's tip
            gate_cfg = live.prepare(miss_q)
            touched = twin._trig[0] if twin._trig else 0
            twin.touch(3.0)
            assert twin._trig is not None and twin._trig[0] == touched + 1  # the sensor captured it
            at_miss = config.model_copy(update={"impact_from_pivot_m": miss_q})  # as the executor does
            fired = live.fire(at_miss, aim, gate_cfg, lambda c: None)
            assert not world.shots[-1].hit
            assert fired.record.recoil_rad_s is None

            live.move(0.5)
            twin.touch(3.0)
            at_hit = config.model_copy(update={"impact_from_pivot_m": 0.5})
            fired = live.fire(at_hit, aim, gate_cfg, lambda c: None)
            truth = world.shots[-1]
            assert truth.hit and truth.recoil_rad_s is not None
            assert fired.record.recoil_rad_s == pytest.approx(abs(truth.recoil_rad_s), rel=0.05)
    finally:
        twin.close()


def test_a_silent_stage_interrupts_the_run_and_nothing_fires_twice(tmp_path: Path) -> None:
    bat = BatSpec.load(SAMPLE_BAT)
    config, world, twin = _twin_config(bat, stage_silent_after=2)
    config = config.model_copy(update={"timeouts": config.timeouts.model_copy(update={"stage_s": 1.0})})
    try:
        with Store.open(tmp_path / "r.db") as store:
            out = certify(store, Procedure.load("bbcor"), bat, config)
            entries = store.entries(out.run_id)
    finally:
        twin.close()
    assert out.status == "interrupted"
    assert "did not acknowledge the move" in out.reason and "\n" not in out.reason
    assert len([e for e in entries if e.kind == "ShotFired"]) == len(world.shots) == world.attempts


@pytest.mark.parametrize(("option", "value"), [("period_hz", 0.0), ("sample_hz", -5.0), ("recoil_window", 0)])
def test_a_rate_or_count_that_is_not_positive_is_refused_in_one_line(
    twin: VxmStageTwin, option: str, value: float
) -> None:
    from rig.core.errors import ConfigError

    with pytest.raises(ConfigError, match=rf"option '{option}' must be > 0"):
        _driver(twin, **{option: value})
