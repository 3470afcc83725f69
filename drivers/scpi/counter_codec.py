"""SCPI universal counter (Keysight 53230A class) as three light gates: the wire, both roles.

Wiring the driver expects: the three screens' outputs OR-ed into channel 1; the counter time-stamps
every rising edge (`CONF:ARR:TST (n),(@1)`). A shot gives 3 inbound stamps then up to 3 rebound
stamps, in time order; the gate of each comes from that order (1, 2, 3, then 3, 2, 1), as the
screens are passed. A shot of 5 stamps has lost one rebound edge, and the order alone cannot say
which: the timing, with the gates' positions, tells it or the shot is refused (`map_stamps`).
Sans-I/O: the driver and the simulated twin both use these functions.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from rig.core.devices import GateConfig, GateCrossing, InstrumentIdentity

N_GATES = 3
GATE_ORDER = (1, 2, 3, 3, 2, 1)  # the screens a ball passes: inbound far to near, rebound near to far
# The two ways a rebound gives 2 stamps, as (gate order, what was missed): under or past the far
# screen (a slow rebound drops below gate 1), or the near screen's edge lost on the rebound.
FIVE_STAMP_CANDIDATES = (((1, 2, 3, 3, 2), "gate 1 at the end"), ((1, 2, 3, 2, 1), "gate 3 on the rebound"))
# A 5-stamp candidate agrees when the measured interval from the inbound gate-3 stamp to the first
# rebound stamp is within REBOUND_GAP_ABS_S + REBOUND_GAP_REL x the interval it predicts. The
# absolute part holds what the prediction leaves out: the ball's contact with the bat (about 1 ms)
# and the bat's recoil; the relative part drag and the speeds' change over the gate distances
# (about 1 % over a metre). [assumed: chosen here, not from a measured rig]
REBOUND_GAP_ABS_S = 2e-3
REBOUND_GAP_REL = 0.05
MAX_EDGES = len(GATE_ORDER)
COUNTER_BITS = 48  # ticks are stamps / resolution; 48 bits hold 5600 s at 20 ps (no wrap in a shot)
NO_VALUE = 9.91e37  # SCPI "not a number": a reading the instrument does not have
CHANNEL = 1


class StampError(ValueError):
    """A shot's stamps cannot be mapped to gates (too few, too many, out of order): refused."""


class ScpiErrorReply(ValueError):
    """A reply that is an SCPI error (`-230,"Data stale"`) where data was asked for."""

    def __init__(self, code: int, text: str) -> None:
        self.code, self.text = code, text
        super().__init__(f"instrument error {code}, {text!r}")


@dataclass(frozen=True)
class CounterSetup:
    """What the host tells the counter, and how it reads the result (rig config options)."""

    expected_edges: int = MAX_EDGES  # stamps the counter waits for (SAMP:COUN)
    # fewest stamps that still give both speeds: 3 inbound + 2 rebound (5 stamps need the gates'
    # positions to tell which rebound screen was missed: map_stamps)
    min_edges: int = 5
    resolution_ps: float = 20.0  # 53230A single-shot resolution (53220A: 100 ps, and no stamps)
    trigger_level_v: float = 1.0  # [assumed] screens' TTL-like output; the threshold sits below its high
    impedance_ohm: float = 1e6  # [assumed] a screen drives a high-impedance input
    measurement_timeout_s: float = 2.0  # SYST:TIM: the counter gives up on missing edges after this
    rate_hz: float = 1e6  # SENS:TST:RATE: the highest, so every edge is stamped (edges are ms apart)

    def __post_init__(self) -> None:
        if not N_GATES <= self.min_edges <= self.expected_edges <= MAX_EDGES:
            raise ValueError(
                f"need {N_GATES} <= min_edges ({self.min_edges}) <= expected_edges "
                f"({self.expected_edges}) <= {MAX_EDGES}"
            )
        if not 1.0 <= self.resolution_ps <= 1e5:
            raise ValueError(f"resolution_ps {self.resolution_ps} outside 1-100000 ps")
        if not 0.001 <= self.measurement_timeout_s <= 600.0:
            raise ValueError(f"measurement_timeout_s {self.measurement_timeout_s} outside 0.001-600 s")
        if not -5.0 <= self.trigger_level_v <= 5.0:
            raise ValueError(f"trigger_level_v {self.trigger_level_v} outside -5..5 V")

    @property
    def resolution_s(self) -> float:
        """One tick of the mapped crossings, s."""
        return self.resolution_ps * 1e-12

    def gate_config(self) -> GateConfig:
        """The gates' counter as rig.measure.speeds sees it: ticks of the resolution."""
        return GateConfig(N_GATES, self.resolution_ps / 1000.0, COUNTER_BITS)


# -- host side: what the driver sends -------------------------------------------------------------
def configure_commands(setup: CounterSetup) -> list[str]:
    """The configuration sent before each INIT (Keysight 53220A/53230A programmer's reference)."""
    return [
        f"SYST:TIM {setup.measurement_timeout_s:g}",
        f"CONF:ARR:TST ({setup.expected_edges}),(@{CHANNEL})",
        f"INP{CHANNEL}:COUP DC",
        f"INP{CHANNEL}:IMP {setup.impedance_ohm:g}",
        f"INP{CHANNEL}:LEV {setup.trigger_level_v:g}",
        f"INP{CHANNEL}:SLOP POS",
        f"SENS:TST:RATE {setup.rate_hz:g}",
        "TRIG:SOUR IMM",
    ]


def parse_idn(text: str) -> InstrumentIdentity:
    """`*IDN?` -> maker, model, serial number, firmware (four comma-separated fields)."""
    fields = [f.strip() for f in text.strip().split(",")]
    if len(fields) != 4 or not all(fields[:2]):
        raise ValueError(f"*IDN? reply {text[:80]!r} is not maker,model,serial,firmware")
    maker, model, serial, firmware = fields
    return InstrumentIdentity(model=model, firmware=firmware, serial_number=serial, maker=maker)


_ERROR = re.compile(r'^\s*([+-]?\d+)\s*,\s*"(.*)"\s*$', re.DOTALL)


def parse_error(text: str) -> tuple[int, str]:
    """`SYST:ERR?` -> (code, message); code 0 is "No error"."""
    match = _ERROR.match(text)
    if match is None:
        raise ValueError(f'SYST:ERR? reply {text[:80]!r} is not code,"message"')
    return int(match.group(1)), match.group(2)


def parse_self_test(text: str) -> int:
    """`*TST?` -> 0 for a pass, another whole number for a failure."""
    try:
        return int(text.strip())
    except ValueError:
        raise ValueError(f"*TST? reply {text[:80]!r} is not a whole number") from None


def parse_stamps(text: str) -> tuple[float | None, ...]:
    """A fetched time-stamp array: the prescaler first (must be 1: every edge stamped), then the
    stamps in s; NO_VALUE (9.91E37) becomes None. ValueError (ScpiErrorReply) for anything else."""
    if _ERROR.match(text):
        raise ScpiErrorReply(*parse_error(text))
    parts = text.strip().split(",")
    if not parts or parts == [""]:
        raise ValueError("empty time-stamp reply")
    values = [_number(p, i) for i, p in enumerate(parts)]
    prescaler = values[0]
    if prescaler != 1.0:
        raise ValueError(f"prescaler {parts[0].strip()!r}: not every edge was stamped (must be 1)")
    return tuple(None if _is_no_value(v) else v for v in values[1:])


def _number(part: str, index: int) -> float:
    token = part.strip()
    if not re.fullmatch(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", token):
        raise ValueError(f"time-stamp field {index} {token[:30]!r} is not a number")
    value = float(token)
    if not math.isfinite(value):
        raise ValueError(f"time-stamp field {index} {token[:30]!r} is not finite")
    return value


def _is_no_value(value: float) -> bool:
    return abs(value - NO_VALUE) <= 1e-6 * NO_VALUE


def map_stamps(
    stamps: Sequence[float | None], setup: CounterSetup, positions_m: Sequence[float] | None = None
) -> tuple[GateCrossing, ...]:
    """Stamps of one shot -> crossings (gate by order, tick = stamp / resolution). Refuses (StampError)
    missing values before real ones, too few or too many stamps, and stamps that do not rise.

    Six stamps (or fewer than five) are mapped by GATE_ORDER. Five stamps have lost one rebound edge:
    the far screen at the end (1, 2, 3, 3, 2) or the near screen on the rebound (1, 2, 3, 2, 1), and
    the rebound speed is computed over another gate pair in each. With the gates' positions
    (`positions_m`, gate 1 farthest, from the impact point: the rig config's [gates] positions_m)
    the timing tells them apart (`five_stamp_order`); without them a 5-stamp shot is refused.
    """
    present = list(stamps)
    while present and present[-1] is None:
        present.pop()
    if any(s is None for s in present):
        raise StampError(f"a stamp is missing in the middle of the shot ({len(stamps)} fetched)")
    real = [float(s) for s in present if s is not None]
    if len(real) > min(setup.expected_edges, MAX_EDGES):
        raise StampError(f"{len(real)} time stamps, more than the {setup.expected_edges} edges expected")
    if len(real) < setup.min_edges:
        raise StampError(
            f"{len(real)} time stamps, fewer than the {setup.min_edges} needed "
            f"({N_GATES} inbound and {setup.min_edges - N_GATES} rebound)"
        )
    ticks = [round(s / setup.resolution_s) for s in real]
    for i in range(1, len(ticks)):
        if ticks[i] <= ticks[i - 1]:
            raise StampError(
                f"time stamps do not rise: stamp {i + 1} ({real[i]!r} s) after {real[i - 1]!r} s"
            )
    if min(ticks) < 0:
        raise StampError(f"negative time stamp {min(real)!r} s")
    order: Sequence[int] = GATE_ORDER
    if len(real) == MAX_EDGES - 1:
        if positions_m is None:
            raise StampError(
                "5 time stamps: which rebound screen was missed cannot be told without the gates' "
                "positions (the driver was not given them)"
            )
        order = five_stamp_order(real, positions_m)
    modulus = 1 << COUNTER_BITS
    return tuple(GateCrossing(g, t % modulus) for g, t in zip(order, ticks, strict=False))


def five_stamp_order(stamps_s: Sequence[float], positions_m: Sequence[float]) -> tuple[int, ...]:
    """The gates of 5 rising stamps, from their timing; StampError ("ambiguous ...") unless exactly one
    of FIVE_STAMP_CANDIDATES agrees.

    The inbound speed is that over gates 2 -> 3 (stamps 2 and 3). Each candidate takes the two
    rebound stamps as its gate pair (c, d), so its rebound speed is (x_d - x_c) / (t5 - t4), and
    predicts the interval from the inbound gate-3 stamp to the first rebound stamp: x3 / v_in (to
    the impact point) + x_c / v_out (back out to gate c). It agrees when the measured t4 - t3 is
    within REBOUND_GAP_ABS_S + REBOUND_GAP_REL x its prediction. Gates spaced so that both
    candidates predict about the same (x2^2 near x1 x3) leave every 5-stamp shot ambiguous.
    """
    if len(stamps_s) != MAX_EDGES - 1:
        raise ValueError(f"five_stamp_order takes 5 stamps, not {len(stamps_s)}")
    x = tuple(float(p) for p in positions_m)
    if len(x) != N_GATES or not x[0] > x[1] > x[2] > 0.0:
        raise ValueError(f"gate positions {tuple(positions_m)} must be three, farthest first, > 0")
    t = [float(s) for s in stamps_s]
    v_in = (x[1] - x[2]) / (t[2] - t[1])
    gap, rebound_dt = t[3] - t[2], t[4] - t[3]
    agree: list[tuple[int, ...]] = []
    fits: list[str] = []
    for order, missed in FIVE_STAMP_CANDIDATES:
        gate_c, gate_d = order[3], order[4]
        x_c, x_d = x[gate_c - 1], x[gate_d - 1]
        v_out = (x_d - x_c) / rebound_dt
        predicted = x[2] / v_in + x_c / v_out
        tolerance = REBOUND_GAP_ABS_S + REBOUND_GAP_REL * predicted
        if abs(gap - predicted) <= tolerance:
            agree.append(order)
        fits.append(f"missed {missed} predicts {predicted * 1e3:.2f} ms")
    if len(agree) == 1:
        return agree[0]
    which = "both agree" if agree else "neither agrees"
    raise StampError(
        f"ambiguous 5-stamp shot: inbound gate 3 to the first rebound stamp took {gap * 1e3:.2f} ms; "
        f"{', '.join(fits)}: {which} within {REBOUND_GAP_ABS_S * 1e3:g} ms + {REBOUND_GAP_REL * 100:g} %"
    )


def format_stamps(stamps: Sequence[float | None], prescaler: int = 1) -> str:
    """Device side: the FETC? reply for `stamps` (None as 9.91E37), prescaler first."""
    fields = [f"+{prescaler}"] + [f"{NO_VALUE:+.14E}" if s is None else f"{s:+.14E}" for s in stamps]
    return ",".join(fields)


# -- device side: parsing a command line ------------------------------------------------------------
# Headers as the programmer's reference spells them: upper case is the short form, the whole the long.
HEADERS = (
    "*IDN?", "*RST", "*CLS", "*TST?", "*OPC?", "SYSTem:ERRor?", "SYSTem:TIMeout",
    "CONFigure:ARRay:TSTamp", "INPut:COUPling", "INPut:IMPedance", "INPut:LEVel", "INPut:SLOPe",
    "SENSe:TSTamp:RATE", "TSTamp:RATE", "TRIGger:SOURce", "SAMPle:COUNt", "INITiate", "FETCh?", "ABORt",
)  # fmt: skip


@dataclass(frozen=True)
class ScpiCommand:
    """One parsed program message: the canonical header (as in HEADERS), its suffix and argument."""

    header: str
    suffix: int | None
    argument: str


def parse_command(line: str, headers: Sequence[str] = HEADERS) -> ScpiCommand | None:
    """The known command `line` is (one of `headers`, spelt as HEADERS spells them), or None (the
    device answers -113 "Undefined header")."""
    text = line.strip()
    head, _, argument = text.partition(" ")
    query = head.endswith("?")
    nodes = head.rstrip("?").lstrip(":").split(":")
    for known in headers:
        if known.endswith("?") != query:
            continue
        suffix = _match_nodes(nodes, known.rstrip("?").split(":"))
        if suffix is not False:
            return ScpiCommand(known, suffix, argument.strip())
    return None


def _match_nodes(tokens: list[str], pattern: list[str]) -> int | bool | None:
    """The numeric suffix (or None) if every token matches its node in short or long form; else False."""
    if len(tokens) != len(pattern):
        return False
    suffix: int | None = None
    for token, node in zip(tokens, pattern, strict=True):
        match = re.fullmatch(r"(\*?[A-Za-z]+)(\d*)", token)
        if match is None:
            return False
        word = match.group(1).upper()
        short = "".join(ch for ch in node if not ch.islower()).upper()
        if word not in (short, node.upper()):
            return False
        if match.group(2):
            suffix = int(match.group(2))
    return suffix


def parse_array_count(argument: str) -> int:
    """`(6),(@1)` -> 6: the count of `CONF:ARR:TST`; ValueError if it is not (n) with n >= 1."""
    match = re.match(r"^\(\s*(\d+)\s*\)", argument.strip())
    if match is None or int(match.group(1)) < 1:
        raise ValueError(f"count {argument[:30]!r} is not (n)")
    return int(match.group(1))
