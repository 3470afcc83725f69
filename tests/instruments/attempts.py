"""Loops two or more instrument tests share: attempts to fire with an interlock open, and writes to
a peer that has hung up until one fails."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable

import pytest

from rig.core.errors import DeviceGone, SafetyRefusal
from rig.drivers.modbus.cannon import ModbusCannon
from rig.simulators.world import SimWorld

INTERLOCK_CASES = ("door", "clamp", "estop", "after-arm")


def fire_with_an_interlock_open(
    world: SimWorld,
    cannon: ModbusCannon,
    after_arm: ModbusCannon,
    attempts: int,
    pressure_kpa: float,
    plc_fires: Callable[[], bool] | None = None,
) -> Counter[str]:
    """`attempts` tries, in turn with the door, the clamp or the e-stop open, or with the door opening
    right after ARM (`after_arm` is on a PLC that does that): each ARM or FIRE must be refused in one
    line, and FIRE written straight to the PLC (`plc_fires`, if given) refused by the PLC too."""
    refused: Counter[str] = Counter()
    world.set_interlock("clamp", True)
    for attempt in range(attempts):
        which = INTERLOCK_CASES[attempt % len(INTERLOCK_CASES)]
        if which == "after-arm":
            after_arm.set_pressure(pressure_kpa)
            after_arm.arm()  # accepted: every interlock closed; then the door opens
            assert not world.interlocks().door
            with pytest.raises(SafetyRefusal, match="FIRE not sent") as info:
                after_arm.fire()
            assert plc_fires is None or not plc_fires()  # the PLC itself refuses too
            world.set_interlock("door", True)
        else:
            cannon.set_pressure(pressure_kpa)
            world.set_interlock(which, False)
            with pytest.raises(SafetyRefusal, match="ARM not sent"):
                cannon.arm()
            with pytest.raises(SafetyRefusal, match="FIRE not sent") as info:
                cannon.fire()
            assert plc_fires is None or not plc_fires()
            world.set_interlock(which, True)
        refused[which] += 1
        assert "\n" not in str(info.value)
    return refused


def write_until_one_fails(write: Callable[[int], None], tries: int = 50) -> tuple[int, DeviceGone] | None:
    """Call `write(i)` for i = 0, 1, ... until one raises DeviceGone (a peer that hung up is found
    out by a later write, not the first): that i and the error, or None if none failed."""
    for i in range(tries):
        try:
            write(i)
        except DeviceGone as exc:
            return i, exc
        time.sleep(0.01)
    return None
