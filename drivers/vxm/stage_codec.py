"""The VXM stepper controller's ASCII command set, both roles, sans I/O (docs/instruments/vxm-stage.md).

Known from users' public code (the maker's manual was not read, instruments.md): `F` on-line
without echo, `C` clear the program, `S<m>M<sps>` speed, `IA<m>M<n>` index motor m to absolute
step n, `I<m>M<n>` relative, `IA<m>M-0` set zero here, `R` run, `V` status (`R` ready, `B`
busy), `X` motor 1's position, `K` kill, `Q` off-line; `^` when a program completes; 9600 baud.
[assumed]: `V` answers one character without a terminator; `X` answers `+0001234\r` (signed
steps); `getDM` (identity) answers `<model> <firmware>\r`; commands in one write are separated by
commas and every write ends in `R` or a comma, so the device can tell where a token ends.

Steps and millimetres: mm = zero_mm + steps * lead. Backlash: every target is reached moving
towards + steps (`StageGeometry.legs`): a target below the current position is passed by the
backlash allowance first, then approached from below, so the nut always bears on the same side.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

LEAD_MM_PER_STEP = 0.00635  # a common lead screw, 0.00635 mm per step (instruments.md, second-hand)
BAUDRATE = 9600
COMPLETE = ord("^")
STATUS_CHARS = "RBJb"  # ready, busy, jog mode, jog busy
IDENTITY_QUERY = "getDM"  # [assumed]
MAX_SPEED_SPS = 6000  # [assumed] the VXM's top speed, steps/s
_POSITION = re.compile(r"^[+-]\d{1,10}$")
_INDEX = re.compile(r"^I(A?)([1-4])M(-?\d{1,9}|-0)$")
_SPEED = re.compile(r"^S([1-4])M(\d{1,5})$")


@dataclass(frozen=True)
class StageGeometry:
    """How steps map to the impact point's distance from the pivot, and the backlash allowance."""

    lead_mm_per_step: float = LEAD_MM_PER_STEP
    zero_mm: float = 0.0  # impact point from the pivot when the stage reads 0 steps
    backlash_mm: float = 0.1  # overshoot before an approach from below [assumed]; >= the screw's play

    def steps_for(self, mm: float) -> int:
        """The step count nearest `mm`."""
        return round((mm - self.zero_mm) / self.lead_mm_per_step)

    def mm_for(self, steps: int) -> float:
        """The impact point at `steps`, mm."""
        return self.zero_mm + steps * self.lead_mm_per_step

    def legs(self, current: int, target: int) -> list[int]:
        """Absolute step targets that end at `target` moving towards + steps (backlash taken up)."""
        if target >= current:
            return [target]
        return [target - math.ceil(self.backlash_mm / self.lead_mm_per_step), target]


def program(legs: list[int], motor: int = 1, speed_sps: int | None = None) -> bytes:
    """`C,S1M<sps>,IA1M<n>,...,R`: clear, set the speed, index to each absolute target, run."""
    parts = ["C"]
    if speed_sps is not None:
        parts.append(f"S{motor}M{int(speed_sps)}")
    parts += [f"IA{motor}M{int(n)}" for n in legs]
    return (",".join(parts) + ",R").encode("ascii")


def encode_position(steps: int) -> bytes:
    """The device's reply to `X`."""
    return f"{steps:+08d}\r".encode("ascii")


def parse_position(text: str) -> int:
    """Steps from an `X` reply line; ValueError if it is not one."""
    if not _POSITION.match(text):
        raise ValueError(f"not a position reply: {text!r}")
    return int(text)


@dataclass(frozen=True)
class Done:
    """`^`: a program completed."""


@dataclass(frozen=True)
class Status:
    """A `V` reply: R ready, B busy, J/b jog."""

    char: str


@dataclass(frozen=True)
class Line:
    """A reply ended by CR (a position, an identity)."""

    text: str


@dataclass(frozen=True)
class Junk:
    """Bytes that are no reply: a garbled or foreign byte."""

    data: bytes


StageItem = Done | Status | Line | Junk


class HostDecoder:
    """The host's side: bytes from the stage -> `Done`, `Status`, `Line`, `Junk`."""

    def __init__(self) -> None:
        self._line = bytearray()

    def feed(self, data: bytes) -> list[StageItem]:
        """Items completed by `data`."""
        out: list[StageItem] = []
        for byte in data:
            ch = chr(byte)
            if byte == COMPLETE and not self._line:
                out.append(Done())
            elif byte in (10, 13):
                if self._line:
                    out.append(self._finish())
            elif byte > 126 or (byte < 32 and byte != 9):
                out.append(Junk(bytes([byte])))
            elif not self._line and ch in STATUS_CHARS:
                out.append(Status(ch))
            else:
                self._line.append(byte)
        return out

    def _finish(self) -> Line:
        text = self._line.decode("ascii")
        self._line.clear()
        return Line(text)


@dataclass(frozen=True)
class Index:
    """`I<m>M<n>` (relative) or `IA<m>M<n>` (absolute); `IA<m>M-0` sets zero (zero=True)."""

    motor: int
    steps: int
    absolute: bool
    zero: bool = False


@dataclass(frozen=True)
class Speed:
    """`S<m>M<sps>`."""

    motor: int
    sps: int


def parse_program_token(token: str) -> Index | Speed:
    """A program token the device stores; ValueError for anything else."""
    m = _INDEX.match(token)
    if m:
        absolute, motor, value = m.group(1) == "A", int(m.group(2)), m.group(3)
        if value == "-0":
            if not absolute:
                raise ValueError("I<m>M-0 (to the negative limit) is not simulated")
            return Index(motor, 0, True, zero=True)
        return Index(motor, int(value), absolute)
    m = _SPEED.match(token)
    if m:
        sps = int(m.group(2))
        if not 1 <= sps <= MAX_SPEED_SPS:
            raise ValueError(f"speed {sps} outside 1-{MAX_SPEED_SPS} steps/s")
        return Speed(int(m.group(1)), sps)
    raise ValueError(f"unknown command {token!r}")


IMMEDIATE = frozenset("FECQRKVXN")  # one-letter commands acted on at once


class DeviceTokenizer:
    """The device's side: the host's bytes -> command tokens (`R`, `V`, `IA1M400`, `getDM`)."""

    def __init__(self) -> None:
        self._tok = ""

    def feed(self, data: bytes) -> list[str]:
        """Tokens completed by `data`."""
        out: list[str] = []
        for ch in data.decode("ascii", errors="replace"):
            if self._tok and (self._tok[0] in "ISP" and ch in "AM0123456789-"):
                self._tok += ch
                continue
            if self._tok and self._tok[0].islower() and ch.isalnum():
                self._tok += ch
                continue
            if self._tok:
                out.append(self._tok)
                self._tok = ""
            if ch in ", \r\n\t":
                continue
            if ch in IMMEDIATE:
                out.append(ch)
            else:
                self._tok = ch
        return out
