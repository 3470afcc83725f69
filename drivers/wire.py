"""The line framing and message grammar every rig device shares (sans-I/O, both roles).

A frame is one ASCII line: ``BODY*CRC\\r\\n`` where CRC is the CRC-16/CCITT-FALSE of BODY as four
upper-case hex digits. BODY is space-separated tokens:

- command (host -> device): ``<seq> <VERB> [ARG ...]``
- reply (device -> host):   ``<seq> OK [FIELD ...]`` or ``<seq> ERR <CODE> [TEXT ...]``
- event (device -> host):   ``! <NAME> [FIELD ...]``

``seq`` is a decimal 1..9999 chosen by the host and echoed in the reply, so a late reply to an
earlier command is never taken for the answer to the current one. Fields are ``KEY=VALUE`` or
positional. Nothing here touches a port: ``feed(bytes)`` returns decoded items, and garbage comes
back as a ``Garbled`` item naming what was wrong, never as an exception.
"""

from __future__ import annotations

from dataclasses import dataclass, field

MAX_LINE = 200  # bytes; a longer run without a newline is garbage
MAX_SEQ = 9999


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): check value 0x29B1 for b'123456789'."""
    crc = 0xFFFF
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ _TABLE[((crc >> 8) ^ byte) & 0xFF]
    return crc


@dataclass(frozen=True)
class Command:
    """A host command: sequence number, verb and arguments."""

    seq: int
    verb: str
    args: tuple[str, ...] = ()


@dataclass(frozen=True)
class Reply:
    """A positive reply to command `seq`."""

    seq: int
    fields: tuple[str, ...] = ()

    def named(self) -> dict[str, str]:
        """The KEY=VALUE fields as a dict."""
        return dict(f.split("=", 1) for f in self.fields if "=" in f)


@dataclass(frozen=True)
class ErrorReply:
    """The device refused command `seq`: a code and a human-readable text."""

    seq: int
    code: str
    text: str = ""


@dataclass(frozen=True)
class Event:
    """An unsolicited event from the device."""

    name: str
    fields: tuple[str, ...] = ()

    def named(self) -> dict[str, str]:
        """The KEY=VALUE fields as a dict."""
        return dict(f.split("=", 1) for f in self.fields if "=" in f)


@dataclass(frozen=True)
class Garbled:
    """Bytes that did not decode to a message, and why."""

    raw: bytes
    reason: str


Message = Command | Reply | ErrorReply | Event
Item = Message | Garbled


def _token_ok(tok: str) -> bool:
    return bool(tok) and all(33 <= ord(c) < 127 and c != "*" for c in tok)


def body_of(msg: Message) -> str:
    """The BODY text of a message (before framing)."""
    if isinstance(msg, Command):
        tokens = [str(msg.seq), msg.verb, *msg.args]
    elif isinstance(msg, Reply):
        tokens = [str(msg.seq), "OK", *msg.fields]
    elif isinstance(msg, ErrorReply):
        tokens = [str(msg.seq), "ERR", msg.code, *msg.text.split()]
    else:
        tokens = ["!", msg.name, *msg.fields]
    for tok in tokens:
        if not _token_ok(tok):
            raise ValueError(f"token {tok!r} cannot be sent: printable ASCII without spaces or '*'")
    return " ".join(tokens)


def encode(msg: Message) -> bytes:
    """Frame one message for the wire."""
    body = body_of(msg).encode("ascii")
    return body + b"*%04X\r\n" % crc16(body)


def parse_body(body: str, role: str) -> Message:
    """Parse a BODY; `role` is who is listening: 'device' expects commands, 'host' the rest."""
    tokens = body.split(" ")
    if any(not t for t in tokens):
        raise ValueError("empty token (double space)")
    head = tokens[0]
    if role == "host" and head == "!":
        if len(tokens) < 2:
            raise ValueError("event without a name")
        return Event(tokens[1], tuple(tokens[2:]))
    if not head.isdigit() or not 1 <= int(head) <= MAX_SEQ:
        raise ValueError(f"bad sequence number {head!r}")
    seq = int(head)
    if len(tokens) < 2:
        raise ValueError("no verb or status")
    if role == "device":
        return Command(seq, tokens[1], tuple(tokens[2:]))
    if tokens[1] == "OK":
        return Reply(seq, tuple(tokens[2:]))
    if tokens[1] == "ERR":
        if len(tokens) < 3:
            raise ValueError("error reply without a code")
        return ErrorReply(seq, tokens[2], " ".join(tokens[3:]))
    raise ValueError(f"status {tokens[1]!r} is neither OK nor ERR")


@dataclass
class LineDecoder:
    """Splits a byte stream into frames, checks each CRC and parses it (one role)."""

    role: str  # "host" (decodes replies and events) or "device" (decodes commands)
    _buf: bytearray = field(default_factory=bytearray)
    _discarding: bool = False

    def __post_init__(self) -> None:
        if self.role not in ("host", "device"):
            raise ValueError(f"role must be 'host' or 'device', not {self.role!r}")

    def feed(self, data: bytes) -> list[Item]:
        """Take bytes as they arrive; return every complete item they finish."""
        out: list[Item] = []
        for byte in data:
            if byte == 0x0A:  # newline ends a frame
                raw = bytes(self._buf)
                self._buf.clear()
                if self._discarding:
                    self._discarding = False
                    out.append(Garbled(raw[:MAX_LINE], f"line longer than {MAX_LINE} bytes"))
                elif raw.strip(b"\r"):
                    out.append(self._decode(raw))
                continue
            if self._discarding:
                continue
            self._buf.append(byte)
            if len(self._buf) > MAX_LINE:
                self._discarding = True
        return out

    @property
    def pending(self) -> int:
        """Bytes held waiting for the end of a line."""
        return len(self._buf)

    def _decode(self, raw: bytes) -> Item:
        line = raw[:-1] if raw.endswith(b"\r") else raw
        star = line.rfind(b"*")
        if star < 0 or len(line) - star != 5:
            return Garbled(raw, "no *CRC trailer")
        body, crc_text = line[:star], line[star + 1 :]
        try:
            crc = int(crc_text.decode("ascii"), 16)
        except (UnicodeDecodeError, ValueError):
            return Garbled(raw, "CRC is not hex")
        if crc != crc16(body):
            return Garbled(raw, f"CRC mismatch (sent {crc:04X}, computed {crc16(body):04X})")
        try:
            text = body.decode("ascii")
        except UnicodeDecodeError:
            return Garbled(raw, "non-ASCII byte")
        try:
            return parse_body(text, self.role)
        except ValueError as exc:
            return Garbled(raw, str(exc))
