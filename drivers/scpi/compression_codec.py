"""Barrel-compression tester (a load cell and a displacement at a fixed compression): the wire, both roles.

The tester squeezes the barrel diametrally between two anvils at the 6 in location until their gap
has closed by a fixed displacement, then reads the load cell: compression is reported as the force
at that fixed displacement (as the field testers read a gauge at a fixed squeeze), never as a
displacement at a fixed force. The wire is SCPI-style text lines on a TCP socket (a VISA TCPIP
SOCKET resource), as the lab's counter speaks:

    *IDN?                    -> maker,model,serial,firmware
    CONFigure:DISPlacement D -> set the fixed displacement, inches
    MEASure:COMPression?     -> "<force lbf>,<displacement reached in>" (the anvils back off after)
    SYSTem:ERRor?            -> code,"message" (0,"No error")
    *RST, *CLS

No maker publishes such a command set for a bat-barrel tester [assumed: this wire is ours, modelled
on SCPI instruments with a load cell and a displacement sensor]. Sans-I/O: the driver and the
simulated twin both use these functions.
"""

from __future__ import annotations

import math
import re

from rig.core.devices import BarrelCompression
from rig.drivers.scpi.counter_codec import ScpiCommand, ScpiErrorReply, parse_command, parse_error

# [assumed] the fixed squeeze: 0.040 in of a 2.61 in barrel (1.5 %), well inside the composite's
# elastic range; no tester's figure was found (lab-practice.md: the BC fixture's loads are unknown)
DISPLACEMENT_IN = 0.040
DISPLACEMENT_RANGE_IN = (0.005, 0.100)  # a squeeze the fixture can make without denting a barrel
MAX_FORCE_LBF = 2000.0  # [assumed] the load cell's capacity
# [assumed] the anvils reach the commanded displacement within this; a larger miss means the load
# cell's limit stopped them (a barrel far stiffer than a bat's) or the fixture slipped
REACHED_TOLERANCE_IN = 0.001
MEASURE_TIMEOUT_S = 30.0  # [assumed] close, hold, read and back off: seconds on a slow fixture

HEADERS = (
    "*IDN?", "*RST", "*CLS", "SYSTem:ERRor?", "CONFigure:DISPlacement", "MEASure:COMPression?",
)  # fmt: skip
NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def check_displacement(displacement_in: float) -> float:
    """`displacement_in` if the fixture can make it, else ValueError naming the range."""
    lo, hi = DISPLACEMENT_RANGE_IN
    if not (math.isfinite(displacement_in) and lo <= displacement_in <= hi):
        raise ValueError(f"displacement {displacement_in!r} in outside {lo:g}-{hi:g} in")
    return displacement_in


# -- host side ---------------------------------------------------------------------------------
def configure_command(displacement_in: float) -> str:
    """The line that sets the fixed displacement."""
    return f"CONF:DISP {check_displacement(displacement_in):.5f}"


MEASURE = "MEAS:COMP?"


def parse_reading(text: str, commanded_in: float) -> BarrelCompression:
    """A MEAS:COMP? reply -> the reading; ScpiErrorReply for an error reply, ValueError (one line)
    for anything malformed or a displacement the anvils did not reach."""
    if text.lstrip().startswith(("-", "+")) and '"' in text:
        raise ScpiErrorReply(*parse_error(text))
    parts = [p.strip() for p in text.strip().split(",")]
    if len(parts) != 2:
        raise ValueError(f"compression reply {text[:60]!r} is not force,displacement")
    force, reached = (_number(p, name) for p, name in zip(parts, ("force", "displacement"), strict=True))
    if not 0.0 <= force <= MAX_FORCE_LBF:
        raise ValueError(f"force {force:g} lbf outside the load cell's 0-{MAX_FORCE_LBF:g} lbf")
    if abs(reached - commanded_in) > REACHED_TOLERANCE_IN:
        raise ValueError(
            f"the anvils reached {reached:.4f} in, not the commanded {commanded_in:.4f} in "
            "(load limit, or the barrel slipped)"
        )
    return BarrelCompression(force_lbf=force, displacement_in=reached)


def _number(token: str, name: str) -> float:
    if not NUMBER.fullmatch(token):
        raise ValueError(f"{name} {token[:30]!r} is not a number")
    return float(token)


# -- device side -------------------------------------------------------------------------------
def parse(line: str) -> ScpiCommand | None:
    """The tester's command `line` is, or None (it answers -113 "Undefined header")."""
    return parse_command(line, HEADERS)


def format_reading(reading: BarrelCompression) -> str:
    """Device side: the MEAS:COMP? reply."""
    return f"{reading.force_lbf:+.6E},{reading.displacement_in:+.6E}"
