"""The swing sensor's ASCII lines, both roles, sans I/O (docs/instruments/vxm-stage.md). [assumed]

No source specifies a bat lab's swing sensor; this is a plausible USB angle encoder with a small
digital I/O box. Commands end in CR; replies and samples end in CRLF:

- `ID?` -> `ID,<maker>,<model>,<serial>,<firmware>`; `RES?` -> `RES,<deg>` (encoder resolution)
- `GRIP 1` / `GRIP 0` -> `LOCK,1` / `LOCK,0` once the grip's lock switch agrees (the box drives the
  grip's valve on an output and reads the switch on an input), or `ERR ...` if it does not in time
- `LOCK?` -> `LOCK,<0|1>`
- `SWING <n>` -> `OK`: the lifter raises the bat to its release angle and drops it; it swings n
  cycles and is caught
- `CAP <n> <hz>` -> `#CAP,<n>`, n sample lines `<t_us>,<angle_deg>`, `#END`: n samples from now
- `ARM <hz> <pre> <post> <deg_s>` -> `OK`: capture `pre` samples before and `post` after the
  angular speed first exceeds deg_s, and keep re-arming
- `TRIG?` -> `#TRIG,<k>,<n>`, n samples, `#END`: the k-th (latest) triggered capture (k = 0: none)
- anything refused -> `ERR <text>`
"""

from __future__ import annotations

from dataclasses import dataclass

BAUDRATE = 115200  # USB CDC: the rate is nominal
MAX_SAMPLES = 65536  # [assumed] the sensor's capture buffer
VERBS = {"ID?": 0, "RES?": 0, "LOCK?": 0, "TRIG?": 0, "GRIP": 1, "SWING": 1, "CAP": 2, "ARM": 4}


@dataclass(frozen=True)
class Command:
    """One command line: its verb and numeric arguments."""

    verb: str
    args: tuple[float, ...]


def encode(verb: str, *args: float) -> bytes:
    """A command line for the sensor."""
    return (" ".join([verb, *(f"{a:g}" for a in args)]) + "\r").encode("ascii")


def parse_command(line: str) -> Command:
    """The device's parse of one command line; ValueError names what is wrong."""
    words = line.strip().split()
    if not words or words[0] not in VERBS:
        raise ValueError(f"unknown command {line.strip()!r}")
    verb, rest = words[0], words[1:]
    if len(rest) != VERBS[verb]:
        raise ValueError(f"{verb} takes {VERBS[verb]} values, got {len(rest)}")
    try:
        return Command(verb, tuple(float(w) for w in rest))
    except ValueError:
        raise ValueError(f"{verb}: not a number in {' '.join(rest)!r}") from None


def encode_sample(t_s: float, angle_deg: float) -> str:
    """One sample line (without its CRLF): microseconds since the sensor started, degrees."""
    return f"{round(t_s * 1e6)},{angle_deg:.4f}"


def parse_sample(line: str) -> tuple[float, float]:
    """(t_s, angle_deg) of a sample line; ValueError if it is not one."""
    t_us, sep, deg = line.partition(",")
    if not sep or not t_us.isdigit():
        raise ValueError(f"not a sample line: {line[:40]!r}")
    return int(t_us) * 1e-6, float(deg)


def encode_lines(lines: list[str]) -> bytes:
    """Lines as the sensor sends them."""
    return "".join(f"{line}\r\n" for line in lines).encode("ascii")


class LineSplitter:
    """Bytes -> complete lines (CR and LF stripped); a non-ASCII byte makes the line garbled."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[str | bytes]:
        """Complete lines: str, or the raw bytes of a garbled one."""
        self._buf += data
        out: list[str | bytes] = []
        while b"\n" in self._buf:
            raw, _, rest = bytes(self._buf).partition(b"\n")
            self._buf = bytearray(rest)
            raw = raw.rstrip(b"\r")
            try:
                text = raw.decode("ascii")
                out.append(text if text.isprintable() else raw)
            except UnicodeDecodeError:
                out.append(raw)
        return out
