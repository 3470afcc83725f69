"""Drivers chosen by configuration (rig.drivers.registry): names, import paths, options, refusals."""

from __future__ import annotations

import pytest

from rig.core.config import RigConfig
from rig.core.errors import ConfigError
from rig.drivers.registry import BUILTIN, known_drivers
from rig.session import RigSession, sim_config
from tests.drivers import lab_drivers


def _sim_devices(**gates: object) -> dict[str, object]:
    """A rig config's mapping with [devices] tables only (no [ports]), on a simulated ideal rig."""
    ports = sim_config("ideal").addresses()
    devices: dict[str, dict[str, object]] = {kind: {"address": url} for kind, url in ports.items()}
    devices["gates"].update(gates)
    return {"devices": devices}


def test_devices_tables_alone_open_the_rig_line_drivers() -> None:
    config = RigConfig.from_dict(_sim_devices())
    assert config.device("cannon").driver == "rig-line"
    with RigSession.open(config) as session:
        assert session.gates.config().gates == 3
        assert session.cannon.status().state.value == "SAFE"
    assert session.traffic and {name for name, _ in session.traffic} >= {"gates", "cannon"}


def test_ports_alone_still_mean_rig_line_and_devices_win_over_ports() -> None:
    ports = sim_config("ideal").addresses()
    config = RigConfig.from_dict({"ports": ports, "devices": {"gates": {"address": "sim://gates?rig=other"}}})
    assert config.device("cannon").address == ports["cannon"]
    assert config.device("gates").address == "sim://gates?rig=other"
    inherits = RigConfig.from_dict({"ports": ports, "devices": {"gates": {"driver": "rig-line"}}})
    assert inherits.device("gates").address == ports["gates"]


def test_a_device_without_an_address_is_refused_in_one_line() -> None:
    with pytest.raises(ConfigError, match=r"no address for gates, clamp"):
        RigConfig.from_dict({"ports": {"cannon": "/dev/ttyUSB0"}})


def test_an_unknown_driver_name_lists_the_known_ones() -> None:
    config = RigConfig.from_dict(_sim_devices(driver="no-such-driver"))
    with pytest.raises(ConfigError) as caught:
        RigSession.open(config)
    text = str(caught.value)
    assert "[devices.gates] no driver 'no-such-driver'" in text and "rig-line" in text
    assert "\n" not in text


def test_a_built_in_driver_of_another_kind_is_refused() -> None:
    name = next((n for n, entry in BUILTIN.items() if "gates" not in entry.factories), None)
    if name is None:
        pytest.skip("every built-in driver drives the gates")
    with pytest.raises(ConfigError, match=rf"driver '{name}' drives the .*, not the gates"):
        RigSession.open(RigConfig.from_dict(_sim_devices(driver=name)))


def test_the_rig_line_driver_refuses_an_option_it_does_not_know() -> None:
    config = RigConfig.from_dict(_sim_devices(options={"baud": 9600}))
    with pytest.raises(ConfigError, match=r"\[devices.gates\] driver does not know option 'baud'"):
        RigSession.open(config)


def test_a_lab_factory_by_import_path_opens_with_its_options() -> None:
    lab_drivers.OPENED.clear()
    config = RigConfig.from_dict(
        _sim_devices(driver="tests.drivers.lab_drivers:counting_gates", options={"label": "bay 2"})
    )
    with RigSession.open(config) as session:
        assert isinstance(session.gates, lab_drivers.CountingGates)
        assert session.gates.config().gates == 3
    assert lab_drivers.OPENED == ["bay 2"]
    assert "gates" in lab_drivers.CLOSED


def test_a_lab_option_of_the_wrong_type_is_refused() -> None:
    config = RigConfig.from_dict(
        _sim_devices(driver="tests.drivers.lab_drivers:counting_gates", options={"label": 2})
    )
    with pytest.raises(ConfigError, match=r"option 'label' must be text, not 2"):
        RigSession.open(config)


@pytest.mark.parametrize(
    ("driver", "says"),
    [
        ("tests.drivers.no_such_module:factory", "cannot import 'tests.drivers.no_such_module'"),
        ("tests.drivers.lab_drivers:no_such_factory", "has no 'no_such_factory'"),
        ("tests.drivers.lab_drivers:NOT_CALLABLE", "is not a factory"),
    ],
)
def test_a_bad_import_path_is_one_line(driver: str, says: str) -> None:
    with pytest.raises(ConfigError) as caught:
        RigSession.open(RigConfig.from_dict(_sim_devices(driver=driver)))
    assert says in str(caught.value) and "\n" not in str(caught.value)


def test_a_device_that_lacks_its_interface_is_refused_and_closed_and_the_others_closed_too() -> None:
    lab_drivers.CLOSED.clear()
    config = RigConfig.from_dict(_sim_devices(driver="tests.drivers.lab_drivers:half_a_gates"))
    with pytest.raises(ConfigError) as caught:
        RigSession.open(config)
    text = str(caught.value)
    assert "lacks arm, crossings, disarm, self_test" in text and "rig.core.devices.Gates" in text
    assert lab_drivers.CLOSED == ["half"]


def test_a_device_marked_simulated_makes_the_rig_simulated() -> None:
    data = _sim_devices()
    plain = {k: {"address": "socket://127.0.0.1:1"} for k in ("cannon", "gates", "clamp")}
    assert not RigConfig.from_dict({"devices": plain}).simulated
    plain["gates"]["simulated"] = True
    assert RigConfig.from_dict({"devices": plain}).simulated
    assert RigConfig.from_dict(data).simulated  # sim:// addresses


def test_known_drivers_start_with_the_built_in_ones() -> None:
    assert known_drivers("gates")[0] == "rig-line"


@pytest.mark.parametrize(
    ("driver", "says"),
    [
        (":factory", "is not package.module:factory"),
        (".relative:factory", "is not package.module:factory"),
        ("tests.drivers.lab_drivers:raising_factory", "failed to open: ZeroDivisionError"),
        (
            "tests.drivers.broken_module:factory",
            "importing 'tests.drivers.broken_module' failed: RuntimeError",
        ),
    ],
)
def test_a_factory_or_module_that_fails_otherwise_is_one_line_too(driver: str, says: str) -> None:
    with pytest.raises(ConfigError) as caught:
        RigSession.open(RigConfig.from_dict(_sim_devices(driver=driver)))
    assert says in str(caught.value) and "\n" not in str(caught.value)
