"""Property tests of the shared line framing (drivers/wire.py): round trips, garbage, bit rot."""

from __future__ import annotations

import itertools

from hypothesis import given, settings
from hypothesis import strategies as st

from rig.drivers.wire import (
    MAX_LINE,
    Command,
    ErrorReply,
    Event,
    Garbled,
    LineDecoder,
    Message,
    Reply,
    crc16,
    encode,
)

token = st.text(
    alphabet=st.characters(min_codepoint=33, max_codepoint=126, exclude_characters="*"),
    min_size=1,
    max_size=12,
)
tokens = st.lists(token, max_size=6).map(tuple)
seqs = st.integers(1, 9999)
commands = st.builds(Command, seqs, token, tokens)
replies = st.builds(Reply, seqs, tokens)
error_replies = st.builds(ErrorReply, seqs, token, st.lists(token, max_size=4).map(" ".join))
events = st.builds(Event, token, tokens)
to_host = st.one_of(replies, error_replies, events)
messages = st.one_of(commands, to_host)


def role_of(msg: Message) -> str:
    return "device" if isinstance(msg, Command) else "host"


def fits(frame: bytes) -> bool:
    return len(frame) - 1 <= MAX_LINE  # everything before the newline is buffered


def split(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    bounds = [0, *points, len(data)]
    return [data[a:b] for a, b in itertools.pairwise(bounds)]


def test_crc_check_value() -> None:
    assert crc16(b"123456789") == 0x29B1


def test_documented_example_frame() -> None:
    assert encode(Command(7, "PSET", ("420.0",))).startswith(b"7 PSET 420.0*")
    assert encode(Reply(7)).endswith(b"\r\n")


@given(messages)
def test_every_message_round_trips_in_its_role(msg: Message) -> None:
    frame = encode(msg)
    items = LineDecoder(role_of(msg)).feed(frame)
    if fits(frame):
        assert items == [msg]
    else:
        assert len(items) == 1 and isinstance(items[0], Garbled)
        assert "longer than" in items[0].reason


@given(st.lists(messages.filter(lambda m: fits(encode(m))), max_size=8), st.lists(st.integers(0, 10**6)))
def test_a_stream_of_frames_decodes_the_same_in_any_chunking(msgs: list[Message], cuts: list[int]) -> None:
    for role in ("host", "device"):
        mine = [m for m in msgs if role_of(m) == role]
        stream = b"".join(encode(m) for m in mine)
        decoder = LineDecoder(role)
        out = [item for chunk in split(stream, cuts) for item in decoder.feed(chunk)]
        assert out == mine


roles = st.sampled_from(["host", "device"])


@given(st.binary(max_size=700), st.lists(st.integers(0, 10**6), max_size=20), roles)
def test_arbitrary_bytes_in_any_chunking_never_raise(data: bytes, cuts: list[int], role: str) -> None:
    whole = LineDecoder(role).feed(data)
    decoder = LineDecoder(role)
    chunked = [item for chunk in split(data, cuts) for item in decoder.feed(chunk)]
    assert chunked == whole
    for item in whole:
        if not isinstance(item, Garbled):  # a valid frame hidden in the bytes must really be there
            assert encode(item).rstrip(b"\r\n") in data


@given(st.binary(max_size=700).map(lambda b: b.replace(b"*", b"")), roles)
def test_garbage_gives_one_garbled_per_line(data: bytes, role: str) -> None:
    items = LineDecoder(role).feed(data)
    lines = data.split(b"\n")[:-1]  # the part after the last newline is still pending
    expected = [ln for ln in lines if len(ln) > MAX_LINE or ln.strip(b"\r")]
    assert len(items) == len(expected)
    assert all(isinstance(item, Garbled) and item.reason for item in items)


@given(
    st.lists(st.one_of(to_host.filter(lambda m: fits(encode(m))), st.binary(max_size=80)), max_size=10),
    st.lists(st.integers(0, 10**6), max_size=10),
)
def test_garbage_lines_between_frames_lose_no_frame(parts: list[object], cuts: list[int]) -> None:
    stream = b"".join(
        encode(p) if not isinstance(p, bytes) else p.replace(b"\n", b"").replace(b"*", b"") + b"\n"
        for p in parts
    )
    decoder = LineDecoder("host")
    out = [item for chunk in split(stream, cuts) for item in decoder.feed(chunk)]
    assert [i for i in out if not isinstance(i, Garbled)] == [p for p in parts if not isinstance(p, bytes)]


@settings(max_examples=300)
@given(messages.filter(lambda m: fits(encode(m))), st.data())
def test_one_flipped_byte_never_decodes_to_another_message(msg: Message, data: st.DataObject) -> None:
    frame = encode(msg)
    i = data.draw(st.integers(0, len(frame) - 1), label="position")
    new = data.draw(st.integers(0, 255).filter(lambda b: b != frame[i]), label="byte")
    mutated = frame[:i] + bytes([new]) + frame[i + 1 :]
    for item in LineDecoder(role_of(msg)).feed(mutated):
        assert isinstance(item, Garbled) or item == msg, (mutated, item)


def test_named_reasons_for_common_damage() -> None:
    frame = encode(Reply(3, ("P=1.0",)))
    assert LineDecoder("host").feed(b"3 OK\r\n")[0].reason == "no *CRC trailer"
    assert LineDecoder("host").feed(frame.replace(b"3 OK", b"4 OK"))[0].reason.startswith("CRC mismatch")
    assert LineDecoder("host").feed(b"3 OK*ZZZZ\r\n")[0].reason == "CRC is not hex"
    assert "longer than" in LineDecoder("host").feed(b"x" * (MAX_LINE + 5) + b"\n")[0].reason
    body = b"0 OK"
    assert "sequence" in LineDecoder("host").feed(body + b"*%04X\n" % crc16(body))[0].reason
    body = b"1 MAYBE"
    assert "neither OK nor ERR" in LineDecoder("host").feed(body + b"*%04X\n" % crc16(body))[0].reason
    body = b"1 OK \xe9"
    assert LineDecoder("host").feed(body + b"*%04X\n" % crc16(body))[0].reason == "non-ASCII byte"


def test_lone_newline_ends_a_frame_and_blank_lines_are_ignored() -> None:
    frame = encode(Event("G", ("N=1", "T=5"))).replace(b"\r\n", b"\n")
    assert LineDecoder("host").feed(b"\r\n\n" + frame) == [Event("G", ("N=1", "T=5"))]


def test_every_single_byte_change_of_some_frames_is_caught() -> None:
    for msg in (Reply(7, ("P=420.0",)), Command(12, "PSET", ("420.0",)), Event("G", ("N=2", "T=123456"))):
        frame = encode(msg)
        for i in range(len(frame)):
            for new in range(256):
                if new == frame[i]:
                    continue
                mutated = frame[:i] + bytes([new]) + frame[i + 1 :]
                for item in LineDecoder(role_of(msg)).feed(mutated):
                    assert isinstance(item, Garbled) or item == msg, (mutated, item)
