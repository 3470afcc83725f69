"""Read a run's recorded device traffic back as the wire commands the host sent.

Independent of the runner's bookkeeping: the Traffic entries hold the raw bytes (base64) of every
frame; these are decoded as each device decodes them (its codec's device side: a command it would
refuse moves nothing), and each cannon FIRE is paired with the
stage position the clamp was last commanded to (MOVE) in the same session (a resume opens the
devices afresh, so a position commanded before it counts for nothing).
"""

from __future__ import annotations

import base64
from collections import Counter
from dataclasses import dataclass
from typing import Any

from rig.drivers.cannon import codec as cannon_codec
from rig.drivers.clamp import codec as clamp_codec
from rig.drivers.codec import CheckedCommand, DeviceCodec
from rig.drivers.gates import codec as gates_codec

SPECS = {"cannon": cannon_codec.SPECS, "clamp": clamp_codec.SPECS, "gates": gates_codec.SPECS}

MM_PER_IN = 25.4
PIVOT_FROM_KNOB_IN = 6.0


@dataclass(frozen=True)
class WireFire:
    """One FIRE the host sent: the shot it was recorded under and the stage position then (mm)."""

    index: int | None
    stage_mm: float | None


def wire_fires(entries: list[Any]) -> list[WireFire]:
    """Every FIRE command in a run's Traffic entries, in order, with the stage position at that moment."""
    fires: list[WireFire] = []
    stage: float | None = None
    decoders: dict[str, DeviceCodec] = {}
    for e in entries:
        if e.kind in ("RunStarted", "RunResumed"):
            stage, decoders = None, {}  # a new session: the stage's position is not known
        if e.kind != "Traffic":
            continue
        for chunk in e.payload["chunks"]:
            if chunk["dir"] != "tx":
                continue
            decoder = decoders.setdefault(chunk["device"], DeviceCodec(SPECS[chunk["device"]]))
            for item in decoder.feed(base64.b64decode(chunk["data_b64"])):
                if not isinstance(item, CheckedCommand):
                    continue
                if chunk["device"] == "clamp" and item.verb == "MOVE":
                    stage = float(item.values[0])  # type: ignore[arg-type]
                elif chunk["device"] == "cannon" and item.verb == "FIRE":
                    fires.append(WireFire(e.payload.get("index"), stage))
    return fires


def expected_stage_mm(bat: dict[str, Any], location_in: float) -> float:
    """The stage position (pivot to impact, mm) for an impact `location_in` from the barrel end."""
    return (bat["length_in"] - PIVOT_FROM_KNOB_IN - location_in) * MM_PER_IN


def check_fires(entries: list[Any]) -> Counter[int]:
    """Assert every FIRE on the wire was at its shot's recorded location; returns FIREs per shot."""
    bat = next(e.payload["bat"] for e in entries if e.kind == "RunStarted")
    where = {e.payload["index"]: e.payload["location_in"] for e in entries if e.kind == "ShotRequested"}
    fires = wire_fires(entries)
    for f in fires:
        assert f.index in where, f"a FIRE recorded under no requested shot ({f})"
        assert f.stage_mm is not None, f"shot {f.index} fired with no stage MOVE in its session"
        want = expected_stage_mm(bat, where[f.index])
        assert abs(f.stage_mm - want) < 0.01, (
            f"shot {f.index} recorded at {where[f.index]} in ({want:.2f} mm) but fired with the "
            f"stage at {f.stage_mm:.2f} mm"
        )
    return Counter(f.index for f in fires if f.index is not None)
