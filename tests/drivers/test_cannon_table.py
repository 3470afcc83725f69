"""The cannon's state table, once: the driver refuses what the simulated cannon refuses.

The expected table below is written from docs/devices/cannon.md (which command each state
accepts, and the state it leads to), not from the codec. Every (state, command) pair is put to
the simulated cannon at the byte level and to the driver over a port that answers everything;
the driver must send exactly the commands the device accepts, and nothing else.
"""

from __future__ import annotations

import pytest

from rig.core.devices import CannonState
from rig.core.errors import DeviceRefused, SafetyRefusal
from rig.drivers.cannon.driver import CannonDriver
from rig.drivers.codec import DeviceCodec
from rig.drivers.wire import Command, ErrorReply, LineDecoder, Reply
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.drivers.cases import FAST, cannon_status
from tests.drivers.fakeport import FakePort, cmd, ok, scripted
from tests.sim.hosts import Rig

SAFE, ARMED, FIRED, FAULT = CannonState.SAFE, CannonState.ARMED, CannonState.FIRED, CannonState.FAULT
P = 395.0
EVERY = {SAFE: SAFE, ARMED: ARMED, FIRED: FIRED, FAULT: FAULT}  # accepted anywhere, no change
# command -> {state it is accepted in: the state right after it}; docs/devices/cannon.md
EXPECTED: dict[str, dict[CannonState, CannonState]] = {
    "ID": EVERY,
    "STATUS": EVERY,
    "ENV": EVERY,
    "PSET": {SAFE: SAFE},
    "ARM": {SAFE: ARMED},
    "FIRE": {ARMED: FIRED},
    "VENT": {SAFE: SAFE, ARMED: SAFE, FIRED: SAFE, FAULT: FAULT},
    "RESET": {FAULT: SAFE},
}
ARGS = {"PSET": (P,)}
CALLS = {
    "ID": lambda d: d.identify(),
    "STATUS": lambda d: d.status(),
    "ENV": lambda d: d.environment(),
    "PSET": lambda d: d.set_pressure(P, wait_ready=False),
    "ARM": lambda d: d.arm(),
    "FIRE": lambda d: d.fire(),
    "VENT": lambda d: d.vent(),
    "RESET": lambda d: d.reset(),
}
PAIRS = [(state, verb) for state in CannonState for verb in EXPECTED]


class AnsweringPort(FakePort):
    """A cannon port that answers every command: STATUS in `state`, anything else OK."""

    def __init__(self, state: CannonState) -> None:
        super().__init__()
        self.state = state
        self._decoder = LineDecoder("device")

    def _match(self) -> None:
        for item in self._decoder.feed(bytes(self._unmatched)):
            assert isinstance(item, Command), item
            values = {"TEMP_C": 21.0, "RH": 50.0} if item.verb == "ENV" else None
            if item.verb == "STATUS":
                values = cannon_status(self.state.value, P, P)
            elif item.verb == "ID":
                values = {"MODEL": "M", "FW": "1", "SN": "2"}
            answer = DeviceCodec.ok(item.seq, values)
            if item.verb == "FIRE":
                answer += DeviceCodec.event("FIRED", {"SHOT": 1})
            self._answer(answer)
        self._unmatched.clear()


def sim_in(state: CannonState) -> Rig:
    """A simulated rig, tank at P and every interlock closed, its cannon put in `state`."""
    rig = Rig(SimWorld(Scene()))
    rig.clamp.ok("CLAMP")
    rig.clamp.drain()
    rig.cannon.ok("PSET", P)
    rig.cannon.drain()
    rig.world.cannon.state = state
    return rig


def driver_sends(state: CannonState, verb: str) -> bool:
    """Whether the driver puts `verb` on the wire when the cannon reports `state`."""
    port = AnsweringPort(state)
    driver = CannonDriver(port, reply_timeout_s=0.1, **FAST[CannonDriver])
    try:
        CALLS[verb](driver)
    except (SafetyRefusal, DeviceRefused) as exc:
        assert f"{verb} not sent" in str(exc)
        assert f"cannon is {state}" in str(exc)
    finally:
        driver.close()
    written = port.verbs_written()
    assert set(written) <= {verb, "STATUS"}, written  # at most a fresh STATUS before it
    return verb in written


@pytest.mark.parametrize(("state", "verb"), PAIRS, ids=[f"{s}-{v}" for s, v in PAIRS])
def test_simulator_and_driver_follow_the_same_table(state: CannonState, verb: str) -> None:
    accepted = state in EXPECTED[verb]
    rig = sim_in(state)
    reply = rig.cannon.send(verb, *ARGS.get(verb, ()))
    if accepted:
        assert isinstance(reply, Reply), reply
        assert rig.world.cannon.state is EXPECTED[verb][state]
    else:
        assert isinstance(reply, ErrorReply) and reply.code == "STATE", reply
        assert rig.world.cannon.state is state
    assert driver_sends(state, verb) is accepted


@pytest.mark.parametrize("state", [ARMED, FIRED, FAULT])
def test_pset_outside_safe_is_refused_before_it_is_sent(state: CannonState) -> None:
    script = [(cmd(1, "STATUS"), ok(1, cannon_status(state.value)))]
    with scripted(CannonDriver, script, **FAST[CannonDriver]) as (cannon, port):
        with pytest.raises(DeviceRefused, match=f"PSET not sent: cannon is {state}, not SAFE") as info:
            cannon.set_pressure(420.0)
        assert port.verbs_written() == ["STATUS"]
    assert (info.value.command, info.value.code) == ("PSET", "STATE")


@pytest.mark.parametrize("state", [SAFE, ARMED, FIRED])
def test_reset_outside_fault_is_refused_before_it_is_sent(state: CannonState) -> None:
    script = [(cmd(1, "STATUS"), ok(1, cannon_status(state.value)))]
    with scripted(CannonDriver, script, **FAST[CannonDriver]) as (cannon, port):
        with pytest.raises(DeviceRefused, match=f"RESET not sent: cannon is {state}, not FAULT"):
            cannon.reset()
        assert port.verbs_written() == ["STATUS"]


def test_vent_needs_no_status_first() -> None:
    with scripted(CannonDriver, [(cmd(1, "VENT"), ok(1))], **FAST[CannonDriver]) as (cannon, port):
        cannon.vent()
    assert port.verbs_written() == ["VENT"]
