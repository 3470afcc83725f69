"""Generic sans-I/O codec over the shared wire format: a device's command table, both roles.

Each device module declares its commands as `CommandSpec`s; `HostCodec` numbers and encodes
commands and decodes replies and events, `DeviceCodec` decodes and checks commands and encodes
replies and events. Neither does any I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

from rig.drivers.wire import (
    MAX_SEQ,
    Command,
    ErrorReply,
    Event,
    Garbled,
    Item,
    LineDecoder,
    Reply,
    encode,
)

ArgCheck = Callable[[str], object]


def number(lo: float, hi: float) -> ArgCheck:
    """An argument check: a finite decimal number within [lo, hi]."""

    def check(text: str) -> float:
        value = float(text)
        if not lo <= value <= hi:  # also refuses NaN
            raise ValueError(f"{text} outside [{lo:g}, {hi:g}]")
        return value

    return check


def integer(lo: int, hi: int) -> ArgCheck:
    """An argument check: a decimal integer within [lo, hi]."""

    def check(text: str) -> int:
        if not text.lstrip("-").isdigit():
            raise ValueError(f"{text!r} is not an integer")
        value = int(text)
        if not lo <= value <= hi:
            raise ValueError(f"{value} outside [{lo}, {hi}]")
        return value

    return check


def token(max_len: int) -> ArgCheck:
    """An argument check: a name of letters, digits, '.', '_' and '-' (1 to `max_len` characters)."""

    def check(text: str) -> str:
        if not 1 <= len(text) <= max_len or not all(
            c.isascii() and (c.isalnum() or c in "._-") for c in text
        ):
            raise ValueError(f"{text!r} is not a name of 1-{max_len} letters, digits, '.', '_' or '-'")
        return text

    return check


@dataclass(frozen=True)
class CommandSpec:
    """One command a device accepts: its verb, argument checks and what it does."""

    verb: str
    args: tuple[ArgCheck, ...] = ()
    doc: str = ""

    def check(self, *args: object) -> tuple[str, ...]:
        """The arguments as sent; ValueError if the device would refuse them."""
        texts = tuple(_fmt(a) for a in args)
        if len(texts) != len(self.args):
            raise ValueError(f"{self.verb} takes {len(self.args)} argument(s), got {len(texts)}")
        for check, text in zip(self.args, texts, strict=True):
            check(text)
        return texts


@dataclass(frozen=True)
class BadCommand:
    """A command frame the device must refuse (unknown verb, wrong arguments)."""

    seq: int
    code: str
    text: str


@dataclass(frozen=True)
class CheckedCommand:
    """A well-formed command with its arguments converted."""

    seq: int
    verb: str
    values: tuple[object, ...]


def _fields(values: Mapping[str, object] | None, positional: Iterable[object] = ()) -> tuple[str, ...]:
    out = [_fmt(v) for v in positional]
    for key, value in (values or {}).items():
        out.append(f"{key}={_fmt(value)}")
    return tuple(out)


def _fmt(value: object) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        if not math.isfinite(value):
            return repr(value)  # 'nan', 'inf': the argument checks then refuse it with a ValueError
        return repr(value) if value != int(value) or abs(value) >= 1e15 else f"{value:.1f}"
    return str(value)


@dataclass
class HostCodec:
    """The host's side: encode numbered commands, decode replies and events."""

    specs: Mapping[str, CommandSpec]
    _next_seq: int = 1
    _decoder: LineDecoder = field(default_factory=lambda: LineDecoder("host"))

    def command(self, verb: str, *args: object) -> tuple[int, bytes]:
        """Number and frame a command; refuses verbs and arguments the device would refuse."""
        spec = self.specs.get(verb)
        if spec is None:
            raise ValueError(f"unknown command {verb!r}")
        texts = spec.check(*args)
        seq = self._next_seq
        self._next_seq = seq % MAX_SEQ + 1
        return seq, encode(Command(seq, verb, texts))

    def feed(self, data: bytes) -> list[Item]:
        """Decode bytes from the device into replies, error replies, events or Garbled."""
        return self._decoder.feed(data)


@dataclass
class DeviceCodec:
    """The device's side: decode and check commands, encode replies and events."""

    specs: Mapping[str, CommandSpec]
    _decoder: LineDecoder = field(default_factory=lambda: LineDecoder("device"))

    def feed(self, data: bytes) -> list[CheckedCommand | BadCommand | Garbled]:
        """Decode bytes from the host; bad commands come back as BadCommand, never raise."""
        out: list[CheckedCommand | BadCommand | Garbled] = []
        for item in self._decoder.feed(data):
            if not isinstance(item, Command):
                out.append(item if isinstance(item, Garbled) else Garbled(b"", "not a command"))
                continue
            spec = self.specs.get(item.verb)
            if spec is None:
                out.append(BadCommand(item.seq, "UNKNOWN", f"no command {item.verb}"))
                continue
            if len(item.args) != len(spec.args):
                out.append(BadCommand(item.seq, "ARGS", f"{item.verb} takes {len(spec.args)} argument(s)"))
                continue
            try:
                values = tuple(check(a) for check, a in zip(spec.args, item.args, strict=True))
            except ValueError as exc:
                out.append(BadCommand(item.seq, "RANGE", str(exc)))
                continue
            out.append(CheckedCommand(item.seq, item.verb, values))
        return out

    @staticmethod
    def ok(seq: int, values: Mapping[str, object] | None = None, *positional: object) -> bytes:
        """Frame a positive reply."""
        return encode(Reply(seq, _fields(values, positional)))

    @staticmethod
    def error(seq: int, code: str, text: str = "") -> bytes:
        """Frame an error reply."""
        return encode(ErrorReply(seq, code, text))

    @staticmethod
    def event(name: str, values: Mapping[str, object] | None = None, *positional: object) -> bytes:
        """Frame an unsolicited event."""
        return encode(Event(name, _fields(values, positional)))


def flag(text: str) -> bool:
    """Parse a 0/1 field."""
    if text not in ("0", "1"):
        raise ValueError(f"expected 0 or 1, got {text!r}")
    return text == "1"
