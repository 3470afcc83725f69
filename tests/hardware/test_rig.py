"""Opt-in checks on the real rig (`pytest --hardware RIG.toml`): talk to every device, never fire.

They run the same drivers as everything else; a lab runs them after wiring changes or before a
certification day. Nothing here arms the cannon.
"""

from __future__ import annotations

import pytest

from rig.core.config import RigConfig
from rig.core.devices import CannonState
from rig.session import RigSession

pytestmark = pytest.mark.hardware


@pytest.fixture(scope="module")
def session(request: pytest.FixtureRequest):
    config = RigConfig.load(request.config.getoption("--hardware"))
    with RigSession.open(config) as s:
        yield s


def test_every_device_identifies(session: RigSession) -> None:
    for device in (session.cannon, session.gates, session.clamp):
        ident = device.identify()
        assert ident.model and ident.firmware and ident.serial_number


def test_cannon_is_safe_and_reports_its_sensors(session: RigSession) -> None:
    status = session.cannon.status()
    assert status.state in (CannonState.SAFE, CannonState.FAULT)
    env = session.cannon.environment()
    assert -10.0 < env.temperature_c < 50.0 and 0.0 <= env.humidity_pct <= 100.0


def test_gates_pass_their_self_test(session: RigSession) -> None:
    cfg = session.gates.config()
    assert cfg.gates == 3 and cfg.tick_ns > 0
    session.gates.self_test()


def test_clamp_reports_its_stage(session: RigSession) -> None:
    status = session.clamp.status()
    assert 100.0 <= status.position_mm <= 900.0
