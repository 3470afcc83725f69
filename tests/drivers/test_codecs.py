"""Argument checks of the device codecs, in both roles: the host refuses what the device would."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.drivers.cannon import codec as cannon
from rig.drivers.clamp import codec as clamp
from rig.drivers.codec import BadCommand, CheckedCommand, DeviceCodec, HostCodec
from rig.drivers.gates import codec as gates
from rig.drivers.wire import MAX_SEQ, Command, Garbled, Reply, crc16, encode
from tests.drivers.fakeport import cmd, ok


@pytest.mark.parametrize(
    ("specs", "verb", "args", "why"),
    [
        (cannon.SPECS, "LAUNCH", (), "unknown command"),
        (cannon.SPECS, "PSET", (), "takes 1 argument"),
        (cannon.SPECS, "FIRE", (1,), "takes 0 argument"),
        (cannon.SPECS, "PSET", (1000.5,), "outside"),
        (cannon.SPECS, "PSET", (-0.1,), "outside"),
        (cannon.SPECS, "PSET", (math.nan,), "outside"),
        (cannon.SPECS, "PSET", (math.inf,), "outside"),
        (cannon.SPECS, "PSET", ("lots",), "could not convert"),
        (clamp.SPECS, "MOVE", (99.9,), "outside"),
        (clamp.SPECS, "MOVE", (900.1,), "outside"),
        (clamp.SPECS, "SWING", (0,), "outside"),
        (clamp.SPECS, "SWING", (101,), "outside"),
        (clamp.SPECS, "SWING", (1.5,), "not an integer"),
        (gates.SPECS, "ARM", ("now",), "takes 0 argument"),
    ],
)
def test_host_refuses_what_the_device_would(specs, verb, args, why) -> None:
    host = HostCodec(specs)
    with pytest.raises(ValueError, match=why):
        host.command(verb, *args)
    assert host.command("ID")[0] == 1  # a refused command uses no sequence number


@pytest.mark.parametrize(
    ("specs", "verb", "args"),
    [
        (cannon.SPECS, "PSET", (0,)),
        (cannon.SPECS, "PSET", (1000.0,)),
        (clamp.SPECS, "MOVE", (100,)),
        (clamp.SPECS, "MOVE", (900.0,)),
        (clamp.SPECS, "SWING", (1,)),
        (clamp.SPECS, "SWING", (100,)),
    ],
)
def test_boundaries_are_accepted_by_both_roles(specs, verb, args) -> None:
    seq, frame = HostCodec(specs).command(verb, *args)
    (checked,) = DeviceCodec(specs).feed(frame)
    assert checked == CheckedCommand(seq, verb, tuple(type(a)(a) for a in args))


def test_sequence_numbers_wrap_after_9999() -> None:
    host = HostCodec(gates.SPECS, _next_seq=MAX_SEQ)
    assert host.command("CLOCK")[0] == MAX_SEQ
    assert host.command("CLOCK")[0] == 1


@pytest.mark.parametrize(
    ("frame", "code"),
    [
        (cmd(4, "LAUNCH"), "UNKNOWN"),
        (cmd(4, "PSET"), "ARGS"),
        (cmd(4, "PSET", "1", "2"), "ARGS"),
        (cmd(4, "PSET", "abc"), "RANGE"),
        (cmd(4, "PSET", "nan"), "RANGE"),
        (cmd(4, "PSET", "1e9"), "RANGE"),
    ],
)
def test_device_refuses_bad_commands_with_a_code(frame: bytes, code: str) -> None:
    (item,) = DeviceCodec(cannon.SPECS).feed(frame)
    assert isinstance(item, BadCommand) and item.seq == 4 and item.code == code


def test_device_reports_garbage_and_ignores_replies_as_commands() -> None:
    device = DeviceCodec(clamp.SPECS)
    (garbled,) = device.feed(b"4 MOVE 200*0000\r\n")
    assert isinstance(garbled, Garbled) and "CRC" in garbled.reason
    (bad,) = device.feed(ok(4))  # a reply echoed back parses as the verb OK
    assert isinstance(bad, BadCommand) and bad.code == "UNKNOWN"
    (swing,) = device.feed(cmd(5, "SWING", "1.5"))
    assert isinstance(swing, BadCommand) and swing.code == "RANGE"


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_pressure_argument_agrees_between_roles(kpa: float) -> None:
    try:
        _seq, frame = HostCodec(cannon.SPECS).command("PSET", kpa)
    except ValueError:
        assert not 0 <= kpa <= cannon.MAX_PRESSURE_KPA
        return
    (checked,) = DeviceCodec(cannon.SPECS).feed(frame)
    assert isinstance(checked, CheckedCommand)
    assert checked.values[0] == pytest.approx(kpa, rel=1e-12, abs=1e-12)


def test_device_frames_decode_on_the_host() -> None:
    frame = DeviceCodec.ok(3, {"P": 420.0, "DOOR": True})
    assert frame == encode(Reply(3, ("P=420.0", "DOOR=1")))
    assert DeviceCodec.event("FIRED", {"SHOT": 7}) == b"! FIRED SHOT=7*%04X\r\n" % crc16(b"! FIRED SHOT=7")
    assert encode(Command(1, "ID")) == cmd(1, "ID")
