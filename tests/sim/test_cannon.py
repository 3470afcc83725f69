"""SimCannon at the byte level: the codec's state table decides, every command is answered once."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.core.devices import CannonState
from rig.drivers.cannon.codec import parse_environment, parse_status, refuse_arm
from rig.drivers.wire import Command, ErrorReply, Reply, encode
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig

P = 395.0
FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def filled(door: bool = True, clamp: bool = True, estop: bool = True) -> Rig:
    """A rig with the tank at P and the interlocks as given."""
    rig = Rig(SimWorld(Scene()))
    if clamp:
        rig.clamp.ok("CLAMP")
        rig.clamp.drain()
    rig.cannon.ok("PSET", P)
    rig.cannon.drain()
    rig.world.set_interlock("door", door)
    rig.world.set_interlock("estop", estop)
    return rig


def code(reply: Reply | ErrorReply | None) -> str:
    return "OK" if isinstance(reply, Reply) else reply.code if reply else "none"


@FAST
@given(door=st.booleans(), clamp=st.booleans(), estop=st.booleans())
def test_arm_refused_with_any_interlock_open(door: bool, clamp: bool, estop: bool) -> None:
    rig = filled(door, clamp, estop)
    status = parse_status(rig.cannon.ok("STATUS"))
    got = code(rig.cannon.send("ARM"))
    if door and clamp and estop:
        assert got == "OK"
    else:
        assert got == "ILK"
        assert refuse_arm(status) is not None  # the codec's table agrees
        assert code(rig.cannon.send("FIRE")) == "STATE"
        assert rig.world.shots == []


@FAST
@given(opened=st.sets(st.sampled_from(["door", "estop", "clamp"]), min_size=1))
def test_an_interlock_opening_while_armed_vents_and_fire_is_refused(opened: set[str]) -> None:
    rig = filled()
    rig.cannon.ok("ARM")
    rig.cannon.drain()
    for name in sorted(opened):
        if name == "clamp":
            rig.clamp.ok("RELEASE")
        else:
            rig.world.set_interlock(name, False)
    events = rig.cannon.drain()
    assert events[0].name == "ILK"
    assert ("STATE", ("S=SAFE",)) in [(e.name, e.fields) for e in events]
    status = parse_status(rig.cannon.ok("STATUS"))
    assert status.state is CannonState.SAFE and status.pressure_kpa == 0.0
    assert code(rig.cannon.send("FIRE")) == "STATE"
    assert rig.world.shots == []


@FAST
@given(
    door=st.booleans(),
    clamp=st.booleans(),
    estop=st.booleans(),
    wait_ready=st.booleans(),
    armed_first=st.booleans(),
)
def test_arm_accepted_exactly_when_the_codec_table_allows(
    door: bool, clamp: bool, estop: bool, wait_ready: bool, armed_first: bool
) -> None:
    rig = Rig(SimWorld(Scene()))
    if clamp:
        rig.clamp.ok("CLAMP")
        rig.clamp.drain()
    rig.cannon.ok("PSET", P)
    if wait_ready:
        rig.cannon.drain()
    if armed_first and wait_ready:
        assert code(rig.cannon.send("ARM")) == ("OK" if clamp else "ILK")
    rig.world.set_interlock("door", door)
    rig.world.set_interlock("estop", estop)
    status = parse_status(rig.cannon.ok("STATUS"))
    reply = rig.cannon.send("ARM")
    assert (code(reply) == "OK") == (refuse_arm(status) is None)


def test_fire_refused_unless_armed(rig: Rig) -> None:
    assert code(rig.cannon.send("FIRE")) == "STATE"  # SAFE, empty tank
    rig.prepare(P)
    assert code(rig.cannon.send("FIRE")) == "STATE"  # SAFE, ready
    rig.cannon.ok("ARM")
    rig.cannon.ok("FIRE")
    assert code(rig.cannon.send("FIRE")) == "STATE"  # FIRED
    assert len(rig.world.shots) == 1


def test_arm_before_the_tank_is_ready_is_refused_with_pressure(rig: Rig) -> None:
    rig.clamp.ok("CLAMP")
    rig.clamp.drain()
    rig.cannon.ok("PSET", P)  # READY is queued for later; nothing has been read yet
    assert code(rig.cannon.send("ARM")) == "PRESSURE"
    ready = [e for e in rig.cannon.drain() if e.name == "READY"]
    assert ready and ready[0].named()["P"] == "395.0"
    assert code(rig.cannon.send("ARM")) == "OK"
    assert code(rig.cannon.send("PSET", 100.0)) == "STATE"  # only in SAFE


def test_refill_takes_virtual_time_and_vent_cancels_ready(rig: Rig) -> None:
    cannon = rig.world.scene.cannon
    rig.cannon.ok("PSET", 300.0)
    rig.cannon.ok("VENT")
    assert [e.name for e in rig.cannon.drain()] == []  # the READY never happens
    rig.cannon.ok("PSET", 300.0)
    t0 = rig.world.clock
    rig.cannon.drain()
    assert rig.world.clock - t0 == 300.0 / cannon.fill_rate_kpa_s + cannon.settle_s


def test_a_shot_cycles_fired_safe_and_refills_on_its_own(rig: Rig) -> None:
    rig.prepare(P)
    before = len(rig.cannon.events)
    rig.cannon.ok("ARM")
    rig.cannon.ok("FIRE")
    rig.cannon.drain()
    events = [(e.name, e.fields) for e in rig.cannon.events[before:]]
    assert events == [
        ("STATE", ("S=ARMED",)),
        ("STATE", ("S=FIRED",)),
        ("FIRED", ("SHOT=1",)),
        ("STATE", ("S=SAFE",)),
        ("READY", ("P=395.0",)),
    ]
    status = parse_status(rig.cannon.ok("STATUS"))
    assert (status.state, status.pressure_kpa, status.shots) == (CannonState.SAFE, P, 1)


def test_reset_only_from_fault_and_env_is_nominal(rig: Rig) -> None:
    assert code(rig.cannon.send("RESET")) == "STATE"
    env = parse_environment(rig.cannon.ok("ENV"))
    assert (env.temperature_c, env.humidity_pct) == (21.0, 50.0)
    ident = rig.cannon.ok("ID").named()
    assert ident["MODEL"] == "SIM-CANNON"


def test_bad_commands_get_error_codes_and_garbled_lines_no_answer(rig: Rig) -> None:
    dev = rig.world.cannon
    dev.write(encode(Command(11, "LAUNCH")))
    dev.write(encode(Command(12, "PSET")))
    dev.write(encode(Command(13, "PSET", ("2000",))))
    dev.write(encode(Command(14, "PSET", ("lots",))))
    dev.write(b"15 STATUS*0000\r\n")  # wrong CRC
    dev.write(b"16 STATUS\r\n")  # no CRC at all
    items = rig.cannon.codec.feed(dev.read())
    assert [(i.seq, i.code) for i in items if isinstance(i, ErrorReply)] == [
        (11, "UNKNOWN"),
        (12, "ARGS"),
        (13, "RANGE"),
        (14, "RANGE"),
    ]
    assert len(items) == 4


VERBS = {
    "cannon": ["ID", "STATUS", ("PSET", 120.0), "ARM", "FIRE", "VENT", "RESET", "ENV"],
    "gates": ["ID", "CFG", "ARM", "DISARM", "TEST", "CLOCK"],
    "clamp": ["ID", "STATUS", "CLAMP", "RELEASE", ("MOVE", 300.0), ("SWING", 2)],
}


@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_every_well_formed_command_is_answered_exactly_once(data: st.DataObject) -> None:
    rig = Rig(SimWorld(Scene()))
    for _ in range(12):
        name = data.draw(st.sampled_from(sorted(VERBS)))
        verb = data.draw(st.sampled_from(VERBS[name]))
        verb, args = (verb, ()) if isinstance(verb, str) else (verb[0], verb[1:])
        host = getattr(rig, name)
        seq, frame = host.codec.command(verb, *args)
        host.device.write(frame)
        replies = [i for i in host.codec.feed(host.device.read()) if isinstance(i, Reply | ErrorReply)]
        assert [r.seq for r in replies] == [seq]
