"""SimClamp: the lock sensor feeds the cannon's interlock, the stage, SWING and RECOIL."""

from __future__ import annotations

import math

import pytest

from rig.core.units import G_STANDARD
from rig.drivers.clamp.codec import parse_period, parse_recoil, parse_status
from rig.drivers.wire import Command, ErrorReply, encode
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig


def test_lock_is_confirmed_after_the_grip_closes_and_reaches_the_cannon(rig: Rig) -> None:
    assert parse_status(rig.clamp.ok("STATUS")).locked is False
    rig.clamp.ok("CLAMP")
    assert rig.world.interlocks().clamp is False  # the sensor has not confirmed yet
    assert [(e.name, e.fields) for e in rig.clamp.drain()] == [("LOCK", ("L=1",))]
    assert rig.world.interlocks().clamp is True
    assert rig.cannon.drain()[-1].named() == {"DOOR": "1", "CLAMP": "1", "ESTOP": "1"}
    rig.clamp.ok("RELEASE")
    assert rig.world.interlocks().clamp is False


def test_release_before_the_lock_confirms_cancels_it(rig: Rig) -> None:
    rig.clamp.ok("CLAMP")
    rig.clamp.ok("RELEASE")
    assert [e.fields for e in rig.clamp.drain()] == [("L=0",)]
    rig.world.advance(5.0)
    assert rig.world.interlocks().clamp is False


def test_stage_moves_at_its_speed_and_is_busy_meanwhile(rig: Rig) -> None:
    rig.clamp.ok("MOVE", 600.0)
    reply = rig.clamp.send("MOVE", 300.0)
    assert isinstance(reply, ErrorReply) and reply.code == "BUSY"
    assert parse_status(rig.clamp.ok("STATUS")).moving
    t0 = rig.world.clock
    assert rig.clamp.drain()[0].named() == {"MM": "600.0"}
    assert rig.world.clock - t0 == pytest.approx(100.0 / rig.world.scene.rig.stage_speed_mm_s)
    status = parse_status(rig.clamp.ok("STATUS"))
    assert (status.position_mm, status.moving) == (600.0, False)
    rig.world.clamp.write(encode(Command(77, "MOVE", ("950",))))  # HostCodec would refuse to send it
    assert rig.clamp.codec.feed(rig.world.clamp.read()) == [ErrorReply(77, "RANGE", "950 outside [100, 900]")]


def test_swing_gives_the_physical_pendulum_period_of_the_true_bat(rig: Rig) -> None:
    reply = rig.clamp.send("SWING", 10)
    assert isinstance(reply, ErrorReply) and reply.code == "STATE"
    rig.clamp.ok("CLAMP")
    rig.clamp.drain()
    rig.clamp.ok("SWING", 10)
    period = parse_period(rig.clamp.drain()[0])
    assert period.cycles == 10 and period.amplitude_deg == 5.0
    bat, pivot = rig.world.scene.bat, rig.world.scene.rig.pivot_from_knob_m
    d = bat.balance_point_m - pivot
    # Back out the MOI the way ASTM F2398 does: small-amplitude correction, then I = m g d T0^2/4pi^2.
    t0 = period.period_s / (1.0 + math.radians(period.amplitude_deg) ** 2 / 16.0)
    moi = bat.mass_kg * G_STANDARD * d * t0**2 / (4.0 * math.pi**2)
    assert moi == pytest.approx(bat.moi_kgm2, rel=1e-6)


def test_recoil_is_reported_only_with_the_recoil_effect(rig: Rig) -> None:
    rig.shot(395.0, position_mm=520.0)
    assert [e.name for e in rig.clamp.drain()] == []
    on = Rig(SimWorld(Scene.model_validate({"effects": [{"kind": "recoil"}]})))
    on.shot(395.0, position_mm=520.0)
    recoil = [parse_recoil(e) for e in on.clamp.drain() if e.name == "RECOIL"]
    shot = on.world.shots[0]
    expected = 0.145 * 0.52 * (shot.impact_speed + shot.rebound_speed) / 0.19
    assert len(recoil) == 1 and recoil[0].omega_rad_s == pytest.approx(expected, abs=1e-4)
