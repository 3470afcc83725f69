"""Scripted exchanges for every driver method that talks to its device, shared by the tests."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rig.core.devices import (
    CannonState,
    CannonStatus,
    ClampStatus,
    Environment,
    GateConfig,
    Interlocks,
    PendulumPeriod,
)
from rig.drivers.base import Identity, LineDriver
from rig.drivers.cannon.driver import CannonDriver
from rig.drivers.clamp.driver import ClampDriver
from rig.drivers.gates.driver import GatesDriver
from tests.drivers.fakeport import Exchange, cmd, event, ok

# event deadlines short enough for tests; reply deadlines are set by `scripted` (0.1 s)
FAST: dict[type[LineDriver], dict[str, float]] = {
    CannonDriver: {"ready_timeout_s": 0.1, "fire_timeout_s": 0.1},
    GatesDriver: {},
    ClampDriver: {
        "lock_timeout_s": 0.1,
        "move_timeout_s": 0.1,
        "swing_timeout_s": 0.1,
        "swing_cycle_timeout_s": 0.0,
    },
}


def cannon_status(
    state: str = "SAFE",
    p: float = 420.0,
    setpoint: float = 420.0,
    door: bool = True,
    clamp: bool = True,
    estop: bool = True,
    shots: int = 0,
) -> dict[str, object]:
    """The fields of a cannon STATUS reply."""
    return {
        "STATE": state,
        "P": p,
        "SET": setpoint,
        "DOOR": door,
        "CLAMP": clamp,
        "ESTOP": estop,
        "SHOTS": shots,
    }


IDENT = {"MODEL": "RIG-1", "FW": "2.3.1", "SN": "0042"}


@dataclass(frozen=True)
class Case:
    """One driver method, the exchanges it makes when all goes well, and what it returns."""

    name: str
    driver: type[LineDriver]
    call: Callable[[Any], object]
    script: list[Exchange]
    result: object = None

    @property
    def first_verb(self) -> str:
        return self.script[0][0].split(b" ")[1].split(b"*")[0].decode()


CASES = [
    Case(
        "cannon.identify",
        CannonDriver,
        lambda d: d.identify(),
        [(cmd(1, "ID"), ok(1, IDENT))],
        Identity("RIG-1", "2.3.1", "0042"),
    ),
    Case(
        "cannon.status",
        CannonDriver,
        lambda d: d.status(),
        [(cmd(1, "STATUS"), ok(1, cannon_status(shots=3)))],
        CannonStatus(CannonState.SAFE, 420.0, 420.0, Interlocks(True, True, True), 3),
    ),
    Case(
        "cannon.set_pressure",
        CannonDriver,
        lambda d: d.set_pressure(420.0),
        [
            (cmd(1, "STATUS"), ok(1, cannon_status())),
            (cmd(2, "PSET", "420.0"), ok(2) + event("READY", {"P": 419.0})),
        ],
    ),
    Case(
        "cannon.set_pressure_no_wait",
        CannonDriver,
        lambda d: d.set_pressure(300, wait_ready=False),
        [(cmd(1, "STATUS"), ok(1, cannon_status())), (cmd(2, "PSET", "300"), ok(2))],
    ),
    Case(
        "cannon.arm",
        CannonDriver,
        lambda d: d.arm(),
        [(cmd(1, "STATUS"), ok(1, cannon_status())), (cmd(2, "ARM"), ok(2))],
    ),
    Case(
        "cannon.fire",
        CannonDriver,
        lambda d: d.fire(),
        [
            (cmd(1, "STATUS"), ok(1, cannon_status("ARMED", shots=6))),
            (cmd(2, "FIRE"), ok(2) + event("FIRED", {"SHOT": 7})),
        ],
        7,
    ),
    Case("cannon.vent", CannonDriver, lambda d: d.vent(), [(cmd(1, "VENT"), ok(1))]),
    Case(
        "cannon.reset",
        CannonDriver,
        lambda d: d.reset(),
        [(cmd(1, "STATUS"), ok(1, cannon_status("FAULT"))), (cmd(2, "RESET"), ok(2))],
    ),
    Case(
        "cannon.environment",
        CannonDriver,
        lambda d: d.environment(),
        [(cmd(1, "ENV"), ok(1, {"TEMP_C": 21.5, "RH": 48.0}))],
        Environment(21.5, 48.0),
    ),
    Case(
        "gates.identify",
        GatesDriver,
        lambda d: d.identify(),
        [(cmd(1, "ID"), ok(1, IDENT))],
        Identity("RIG-1", "2.3.1", "0042"),
    ),
    Case(
        "gates.config",
        GatesDriver,
        lambda d: d.config(),
        [(cmd(1, "CFG"), ok(1, {"N": 3, "TICK_NS": 100.0, "BITS": 32}))],
        GateConfig(3, 100.0, 32),
    ),
    Case("gates.arm", GatesDriver, lambda d: d.arm(), [(cmd(1, "ARM"), ok(1))]),
    Case("gates.disarm", GatesDriver, lambda d: d.disarm(), [(cmd(1, "DISARM"), ok(1))]),
    Case(
        "gates.self_test", GatesDriver, lambda d: d.self_test(), [(cmd(1, "TEST"), ok(1, {"RESULT": "PASS"}))]
    ),
    Case(
        "gates.clock",
        GatesDriver,
        lambda d: d.clock(),
        [(cmd(1, "CLOCK"), ok(1, {"T": 4294967295}))],
        4294967295,
    ),
    Case(
        "clamp.identify",
        ClampDriver,
        lambda d: d.identify(),
        [(cmd(1, "ID"), ok(1, IDENT))],
        Identity("RIG-1", "2.3.1", "0042"),
    ),
    Case(
        "clamp.status",
        ClampDriver,
        lambda d: d.status(),
        [(cmd(1, "STATUS"), ok(1, {"LOCK": 1, "POS": 512.5, "MOVING": 0, "DEG": -0.25}))],
        ClampStatus(True, 512.5, False, -0.25),
    ),
    Case(
        "clamp.clamp", ClampDriver, lambda d: d.clamp(), [(cmd(1, "CLAMP"), ok(1) + event("LOCK", {"L": 1}))]
    ),
    Case(
        "clamp.release",
        ClampDriver,
        lambda d: d.release(),
        [(cmd(1, "RELEASE"), ok(1) + event("LOCK", {"L": 0}))],
    ),
    Case(
        "clamp.move_to",
        ClampDriver,
        lambda d: d.move_to(450.0),
        [(cmd(1, "MOVE", "450.0"), ok(1) + event("POS", {"MM": 450.1}))],
    ),
    Case(
        "clamp.measure_period",
        ClampDriver,
        lambda d: d.measure_period(10),
        [(cmd(1, "SWING", 10), ok(1) + event("PERIOD", {"US": 1500000, "AMP": 5.0, "N": 10}))],
        PendulumPeriod(1.5, 5.0, 10),
    ),
]
