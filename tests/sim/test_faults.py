"""The faulty scene: each scheduled fault shows up on its shot, as docs/simulation.md says."""

from __future__ import annotations

import pytest

from rig.core.devices import CannonState
from rig.drivers.cannon.codec import parse_status
from rig.drivers.gates.codec import parse_crossing
from rig.drivers.wire import ErrorReply, Reply
from rig.simulators.device import Unplugged
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig

P = 395.0


def gates_of(events: list) -> list[int]:
    return [parse_crossing(e).gate for e in events if e.name == "G"]


def fire(rig: Rig) -> list:
    rig.prepare(P)
    rig.cannon.ok("ARM")
    rig.cannon.ok("FIRE")
    return rig.gates.drain()


@pytest.fixture(scope="module")
def faulty() -> Scene:
    return Scene.load("faulty")


def test_each_fault_of_the_faulty_scene_strikes_its_shot(faulty: Scene) -> None:
    rig = Rig(SimWorld(faulty))
    # 1: a clean shot, with the recoil event.
    assert gates_of(fire(rig)) == [1, 2, 3, 3, 2, 1]
    assert [e.name for e in rig.clamp.drain()] == ["RECOIL"]

    # 2: misfire - FIRE is accepted, then FAULT; no ball; the tank is vented; RESET clears it.
    rig.cannon.drain()
    assert gates_of(fire(rig)) == []
    names = [(e.name, e.fields) for e in rig.cannon.drain()]
    assert ("FAULT", ("CODE=MISFIRE",)) in names and names[-1] == ("STATE", ("S=FAULT",))
    status = parse_status(rig.cannon.ok("STATUS"))
    assert (status.state, status.pressure_kpa, status.shots) == (CannonState.FAULT, 0.0, 1)
    assert isinstance(rig.cannon.send("ARM"), ErrorReply)
    rig.cannon.ok("RESET")
    assert len(rig.world.shots) == 1

    # 3: gate 2 misses the inbound ball.
    assert gates_of(fire(rig)) == [1, 3, 3, 2, 1]

    # 4: gate 1 triggers twice, 40 us apart.
    events = fire(rig)
    assert gates_of(events) == [1, 1, 2, 3, 3, 2, 1]
    first, echo = (parse_crossing(e).tick for e in events[:2])
    assert echo - first == 400

    # 5: the first gate event arrives garbled (CRC mismatch); the other five are fine.
    assert gates_of(fire(rig)) == [2, 3, 3, 2, 1]
    assert len(rig.gates.garbled) == 1 and "CRC mismatch" in rig.gates.garbled[0].reason

    # 6: the first STATUS after shot 5 gets no reply; the command after it is answered.
    rig.cannon.drain()
    assert rig.cannon.send("STATUS") is None
    assert isinstance(rig.cannon.send("STATUS"), Reply)
    assert gates_of(fire(rig)) == [1, 2, 3, 3, 2, 1]

    # 7: the gates vanish after two beam breaks, until plugged back in.
    assert gates_of(fire(rig)) == [1, 2]
    with pytest.raises(Unplugged):
        rig.gates.drain()
    with pytest.raises(Unplugged):
        rig.gates.send("ID")
    rig.world.gates.replug()
    assert isinstance(rig.gates.send("ID"), Reply)

    # 8: the door opens right after ARM: vent to SAFE, FIRE refused; it closes 2 s later.
    rig.prepare(P)
    rig.cannon.ok("ARM")
    events = [(e.name, e.fields) for e in rig.cannon.drain()]
    assert events == [
        ("STATE", ("S=ARMED",)),
        ("ILK", ("DOOR=0", "CLAMP=1", "ESTOP=1")),
        ("STATE", ("S=SAFE",)),
        ("ILK", ("DOOR=1", "CLAMP=1", "ESTOP=1")),
    ]
    refused = rig.cannon.send("FIRE")
    assert isinstance(refused, ErrorReply) and refused.code == "STATE"
    assert gates_of(fire(rig)) == [1, 2, 3, 3, 2, 1]  # door closed again: shot 8 goes
    assert len(rig.world.shots) == 7


def scene_with(**fault: object) -> Scene:
    return Scene.model_validate({"seed": fault.pop("seed", 0), "effects": [fault]})


def test_probability_one_strikes_every_time() -> None:
    rig = Rig(SimWorld(scene_with(kind="garbled", device="gates", probability=1.0)))
    assert gates_of(fire(rig)) == []
    assert len(rig.gates.garbled) == 6


def test_random_faults_are_repeatable_with_the_seed() -> None:
    def pattern(seed: int) -> list[list[int]]:
        rig = Rig(SimWorld(scene_with(kind="missed_trigger", gate=3, probability=0.5, seed=seed)))
        return [gates_of(fire(rig)) for _ in range(12)]

    assert pattern(1) == pattern(1)
    assert pattern(1) != pattern(2)
    assert [1, 2, 3, 3, 2, 1] in pattern(1) and [1, 2, 3, 2, 1] in pattern(1)


def test_a_dropped_reply_still_takes_effect() -> None:
    rig = Rig(SimWorld(scene_with(kind="dropped_reply", device="cannon", name="PSET", shots=[1])))
    assert rig.cannon.send("PSET", 200.0) is None  # the host read on, past the READY event
    assert [e.name for e in rig.cannon.events] == ["READY"]
    assert parse_status(rig.cannon.ok("STATUS")).setpoint_kpa == 200.0
