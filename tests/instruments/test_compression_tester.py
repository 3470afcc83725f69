"""The barrel-compression tester: codec, driver against the twin over TCP (faults included), registry."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core.config import DeviceSpec, Timeouts
from rig.core.devices import BarrelCompression
from rig.core.errors import ConfigError, DeviceRefused, DeviceTimeout, GarbledReply
from rig.drivers.registry import DriverContext, open_device
from rig.drivers.scpi import compression_codec as codec
from rig.drivers.scpi.compression import ScpiCompressionTester
from rig.drivers.scpi.counter_codec import ScpiErrorReply
from rig.simulators.instruments.compression_tester import CompressionTesterTwin
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld

GENEROUS = Timeouts(reply_s=10.0)  # a busy machine: the twin's thread may wait for a core


# -- codec ----------------------------------------------------------------------------------------
@given(
    force=st.floats(0.0, codec.MAX_FORCE_LBF),
    displacement=st.floats(*codec.DISPLACEMENT_RANGE_IN),
)
def test_a_reading_survives_the_wire(force: float, displacement: float) -> None:
    sent = BarrelCompression(force_lbf=force, displacement_in=displacement)
    back = codec.parse_reading(codec.format_reading(sent), displacement)
    assert back.force_lbf == pytest.approx(force, rel=1e-6, abs=1e-9)
    assert back.displacement_in == pytest.approx(displacement, rel=1e-6)


@pytest.mark.parametrize(
    ("reply", "said"),
    [
        ("+2.4E+02", "is not force,displacement"),
        ("+2.4E+02,+4.0E-02,+1", "is not force,displacement"),
        ("abc,+4.0E-02", "force 'abc' is not a number"),
        ("+2.4E+02,nan", "displacement 'nan' is not a number"),
        ("+9.0E+03,+4.0E-02", "outside the load cell's"),
        ("-1.0E+00,+4.0E-02", "outside the load cell's"),
        ("+2.4E+02,+3.0E-02", "the anvils reached 0.0300 in, not the commanded 0.0400 in"),
        ("", "is not force,displacement"),
    ],
)
def test_a_malformed_reply_is_refused_in_one_line(reply: str, said: str) -> None:
    with pytest.raises(ValueError) as caught:
        codec.parse_reading(reply, 0.040)
    assert said in str(caught.value) and "\n" not in str(caught.value)


def test_an_error_reply_is_told_from_a_reading() -> None:
    with pytest.raises(ScpiErrorReply) as caught:
        codec.parse_reading('-241,"Hardware missing"', 0.040)
    assert caught.value.code == -241 and caught.value.text == "Hardware missing"


def test_commands_parse_in_short_and_long_form() -> None:
    assert codec.parse("MEAS:COMP?").header == "MEASure:COMPression?"  # type: ignore[union-attr]
    assert codec.parse("configure:displacement 0.04").argument == "0.04"  # type: ignore[union-attr]
    assert codec.parse("FETC?") is None
    with pytest.raises(ValueError, match=r"outside 0\.005-0\.1 in"):
        codec.configure_command(0.5)


# -- driver against the twin ----------------------------------------------------------------------
def world(scene: str = "composite") -> SimWorld:
    return SimWorld(Scene.load(scene))


def serve(sim: SimWorld, **faults: int) -> CompressionTesterTwin:
    twin = CompressionTesterTwin(sim, **faults)
    twin.start()
    return twin


def driver(twin: CompressionTesterTwin, **options: float) -> ScpiCompressionTester:
    context = DriverContext(
        kind="compression",
        name="compression",
        address=twin.address,
        options=options,
        timeouts=GENEROUS,
    )
    device: ScpiCompressionTester = open_device("compression", context, DeviceSpec(**twin.device_table()))
    return device


@pytest.fixture
def composite() -> Iterator[tuple[SimWorld, CompressionTesterTwin]]:
    sim = world()
    twin = serve(sim)
    yield sim, twin
    twin.close()


def test_the_driver_reads_the_barrels_force_at_the_fixed_squeeze(
    composite: tuple[SimWorld, CompressionTesterTwin],
) -> None:
    sim, twin = composite
    device = driver(twin)
    try:
        assert device.identify().model == "BCT-SIM"
        readings = [device.measure_compression() for _ in range(5)]
    finally:
        device.close()
    assert sim.barrel is not None
    k0 = sim.barrel.config.stiffness_lbf_per_in
    for got in readings:
        assert got.displacement_in == pytest.approx(codec.DISPLACEMENT_IN)
        # the new barrel: K0 delta, within 5 SD of the load cell's noise
        assert abs(got.force_lbf - k0 * codec.DISPLACEMENT_IN) < 5 * sim.barrel.config.noise_lbf
    assert [r.force_lbf for r in readings] == pytest.approx([r.force_lbf for r in twin.readings], rel=1e-6)
    assert "CONF:DISP 0.04000" in twin.received


def test_the_displacement_option_reaches_the_tester(
    composite: tuple[SimWorld, CompressionTesterTwin],
) -> None:
    sim, twin = composite
    device = driver(twin, displacement_in=0.02)
    try:
        got = device.measure_compression()
    finally:
        device.close()
    assert got.displacement_in == pytest.approx(0.02)
    assert sim.barrel is not None
    assert got.force_lbf == pytest.approx(
        sim.barrel.true_force_lbf(0.02), abs=5 * sim.barrel.config.noise_lbf
    )


def test_a_silent_tester_times_out_in_one_line_and_the_next_reading_works() -> None:
    sim = world()
    twin = serve(sim, silent_on=1)
    device = driver(twin, measure_timeout_s=1.0)
    try:
        with pytest.raises(DeviceTimeout) as caught:
            device.measure_compression()
        assert "no reply to MEAS:COMP?" in str(caught.value) and "\n" not in str(caught.value)
        assert device.measure_compression().force_lbf > 0.0  # reopened: no late reply taken for this one
    finally:
        device.close()
        twin.close()


@pytest.mark.parametrize(
    ("fault", "said"),
    [("garble_on", "not ASCII"), ("slip_on", "the anvils reached 0.0300 in")],
)
def test_a_garbled_or_short_reading_is_refused_in_one_line(fault: str, said: str) -> None:
    sim = world()
    twin = serve(sim, **{fault: 1})
    device = driver(twin)
    try:
        with pytest.raises(GarbledReply) as caught:
            device.measure_compression()
        assert said in str(caught.value) and "\n" not in str(caught.value)
    finally:
        device.close()
        twin.close()


def test_a_world_without_a_softening_barrel_has_nothing_to_squeeze() -> None:
    twin = serve(world("lab"))
    device = driver(twin)
    try:
        with pytest.raises(DeviceRefused, match="Hardware missing"):
            device.measure_compression()
    finally:
        device.close()
        twin.close()


def test_an_unknown_option_or_a_bad_displacement_is_a_config_line() -> None:
    twin = serve(world())
    try:
        with pytest.raises(ConfigError, match="does not know option 'force'"):
            driver(twin, force=1.0)
        with pytest.raises(ConfigError, match="displacement_in"):
            driver(twin, displacement_in=0.5)
    finally:
        twin.close()


def test_nothing_listening_is_one_line() -> None:
    twin = serve(world())
    address = twin.address
    twin.close()
    context = DriverContext(
        kind="compression", name="compression", address=address, options={}, timeouts=GENEROUS
    )
    with pytest.raises(Exception) as caught:
        open_device("compression", context, DeviceSpec(driver="scpi-compression", address=address))
    assert "compression" in str(caught.value) and "\n" not in str(caught.value)
