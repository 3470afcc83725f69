"""A scripted pyserial-like port for driver tests (in the spirit of PyMeasure's expected_protocol).

The script is a list of exchanges ``(expected bytes written, answer)``. Each write must match the
next exchange exactly; the answer (bytes) then becomes readable. An answer may also be one of
the faults below. `assert_done()` checks that every exchange was consumed and nothing else was
written.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any, TypeVar

from rig.drivers.base import LineDriver
from rig.drivers.codec import DeviceCodec
from rig.drivers.wire import Command, ErrorReply, LineDecoder, Reply, encode


@dataclass(frozen=True)
class Fault:
    """A scripted misbehaviour instead of an answer."""

    name: str


SILENT = Fault("silent")  # the command is taken, nothing is answered
VANISH = Fault("vanish")  # the command is taken, then the port dies (reads and writes raise OSError)
WRITE_FAILS = Fault("write fails")  # writing the command raises OSError; the port is dead

Answer = bytes | Fault
Exchange = tuple[bytes, Answer]


def cmd(seq: int, verb: str, *args: object) -> bytes:
    """The frame the host sends for a command."""
    return encode(Command(seq, verb, tuple(str(a) for a in args)))


def ok(seq: int, values: Mapping[str, object] | None = None, *positional: object) -> bytes:
    """A positive reply frame."""
    return DeviceCodec.ok(seq, values, *positional)


def err(seq: int, code: str, text: str = "") -> bytes:
    """An error reply frame."""
    return DeviceCodec.error(seq, code, text)


def event(name: str, values: Mapping[str, object] | None = None, *positional: object) -> bytes:
    """An event frame."""
    return DeviceCodec.event(name, values, *positional)


class FakePort:
    """A pyserial-like port answering a script; thread-safe like a real one."""

    def __init__(self, script: Iterable[Exchange] = (), *, timeout: float = 0.01, chunk: int = 0) -> None:
        self.timeout: float | None = timeout
        self.port = "fake://scripted"
        self.chunk = chunk  # >0: read() hands out at most this many bytes (exercises reassembly)
        self.open_error: OSError | None = None  # set to make open() (a reconnect) fail
        self.opens = 0
        self._script = list(script)
        self._done = 0
        self._written = bytearray()
        self._unmatched = bytearray()
        self._rx = bytearray()
        self._dead = False
        self._open = True
        self._problems: list[str] = []
        self._timers: list[threading.Timer] = []
        self._cv = threading.Condition()

    # -- pyserial's side --------------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        return self._open

    @property
    def in_waiting(self) -> int:
        with self._cv:
            self._check()
            return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        with self._cv:
            self._check()
            if not self._rx:
                self._cv.wait(self.timeout)
                self._check()
            n = min(size, self.chunk or size, len(self._rx))
            out = bytes(self._rx[:n])
            del self._rx[:n]
            return out

    def write(self, data: bytes) -> int:
        with self._cv:
            self._check()
            self._written += data
            self._unmatched += data
            self._match()
            return len(data)

    def cancel_read(self) -> None:
        with self._cv:
            self._cv.notify_all()

    def close(self) -> None:
        with self._cv:
            self._open = False
            for timer in self._timers:
                timer.cancel()
            self._cv.notify_all()

    def open(self) -> None:
        with self._cv:
            self.opens += 1
            if self.open_error is not None:
                raise self.open_error
            self._open, self._dead = True, False
            self._rx.clear()

    # -- the test's side --------------------------------------------------------------------

    def inject(self, data: bytes, delay_s: float = 0.0) -> None:
        """Make bytes readable (now, or after `delay_s` from another thread)."""
        if delay_s > 0:
            timer = threading.Timer(delay_s, self.inject, (data,))
            timer.daemon = True
            self._timers.append(timer)
            timer.start()
            return
        with self._cv:
            self._rx += data
            self._cv.notify_all()

    def vanish(self) -> None:
        """Unplug: every read and write raises OSError until open()."""
        with self._cv:
            self._dead = True
            self._cv.notify_all()

    @property
    def written(self) -> bytes:
        """Every byte the host wrote."""
        with self._cv:
            return bytes(self._written)

    def verbs_written(self) -> list[str]:
        """The verbs of every command frame the host wrote (decoded as a device would)."""
        return [c.verb for c in LineDecoder("device").feed(self.written) if isinstance(c, Command)]

    def assert_done(self) -> None:
        """Every exchange consumed, nothing written beyond the script, no mismatch."""
        with self._cv:
            assert not self._problems, self._problems
            left = self._script[self._done :]
            assert not left, f"exchanges never reached: {left}"
            assert not self._unmatched, f"partial write never completed: {bytes(self._unmatched)!r}"

    # -- internals --------------------------------------------------------------------------

    def _check(self) -> None:
        if self._dead:
            raise OSError(5, "Input/output error (device unplugged)")
        if not self._open:
            raise OSError(9, "port not open")

    def _match(self) -> None:
        while self._unmatched and self._done < len(self._script):
            expected, answer = self._script[self._done]
            if not self._unmatched.startswith(expected):
                if expected.startswith(bytes(self._unmatched)):
                    return  # a partial write: wait for the rest
                problem = f"exchange {self._done}: expected {expected!r}, written {bytes(self._unmatched)!r}"
                self._problems.append(problem)
                raise AssertionError(problem)
            del self._unmatched[: len(expected)]
            self._done += 1
            self._answer(answer)
        if self._unmatched and self._done >= len(self._script):
            problem = f"written beyond the script: {bytes(self._unmatched)!r}"
            self._problems.append(problem)
            raise AssertionError(problem)

    def _answer(self, answer: Answer) -> None:
        if answer is VANISH:
            self._dead = True
        elif answer is WRITE_FAILS:
            self._dead = True
            raise OSError(5, "Input/output error (write failed)")
        elif isinstance(answer, bytes):
            self._rx += answer
        self._cv.notify_all()

    def __enter__(self) -> FakePort:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def shift(script: Iterable[Exchange], by: int) -> list[Exchange]:
    """The same script with every sequence number raised by `by` (for a script run later)."""
    out: list[Exchange] = []
    for expected, answer in script:
        (command,) = LineDecoder("device").feed(expected)
        assert isinstance(command, Command)
        new_expected = encode(Command(command.seq + by, command.verb, command.args))
        if isinstance(answer, bytes):
            items = LineDecoder("host").feed(answer)
            answer = b"".join(
                encode(replace(i, seq=i.seq + by) if isinstance(i, Reply | ErrorReply) else i)  # type: ignore[arg-type]
                for i in items
            )
        out.append((new_expected, answer))
    return out


def corrupt(frame: bytes) -> bytes:
    """The same frame with one body byte changed, so its CRC no longer matches."""
    i = 0 if frame[:1] != b"X" else 1
    return frame[:i] + (b"Y" if frame[i : i + 1] == b"X" else b"X") + frame[i + 1 :]


D = TypeVar("D", bound=LineDriver)


@contextmanager
def scripted(
    driver_cls: type[D], script: Iterable[Exchange] = (), *, check: bool = True, chunk: int = 0, **kw: Any
) -> Iterator[tuple[D, FakePort]]:
    """A driver on a scripted port (reply timeout 0.1 s); checks the script was used up."""
    port = FakePort(script, chunk=chunk)
    kw.setdefault("reply_timeout_s", 0.1)
    driver = driver_cls(port, **kw)
    try:
        yield driver, port
    finally:
        driver.close()
    if check:
        port.assert_done()
