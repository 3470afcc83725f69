"""Light-gate wire codec (see docs/devices/gates.md).

One counter-timer serves three gates. Every beam break is streamed at once as ``! G N=<gate>
T=<tick>``; the tick counter is BITS wide and wraps, so differences are taken modulo 2^BITS.
"""

from __future__ import annotations

from rig.core.devices import GateConfig, GateCrossing
from rig.drivers.codec import CommandSpec
from rig.drivers.wire import Event, Reply

N_GATES = 3


def elapsed_ticks(earlier: int, later: int, bits: int) -> int:
    """Ticks from `earlier` to `later` on a counter that wraps at 2^bits (less than one wrap)."""
    return (later - earlier) % (1 << bits)


SPECS = {
    s.verb: s
    for s in (
        CommandSpec("ID", (), "identify: MODEL=, FW=, SN="),
        CommandSpec("CFG", (), "N= gates, TICK_NS= counter tick, BITS= counter width"),
        CommandSpec("ARM", (), "start streaming beam breaks"),
        CommandSpec("DISARM", (), "stop streaming beam breaks"),
        CommandSpec("TEST", (), "self-test every beam: RESULT=PASS, or RESULT=FAIL GATE=n"),
        CommandSpec("CLOCK", (), "current counter value T="),
    )
}


def parse_config(reply: Reply) -> GateConfig:
    """Typed view of a CFG reply."""
    named = reply.named()
    try:
        cfg = GateConfig(int(named["N"]), float(named["TICK_NS"]), int(named["BITS"]))
    except KeyError as exc:
        raise ValueError(f"CFG reply lacks field {exc.args[0]}") from None
    if cfg.gates < 1 or not cfg.tick_ns > 0 or not 8 <= cfg.bits <= 64:
        raise ValueError(f"implausible gate configuration {cfg}")
    return cfg


def parse_crossing(event: Event, gates: int = N_GATES) -> GateCrossing:
    """Typed view of a ``G`` event; raises ValueError for a bad gate number or tick."""
    named = event.named()
    try:
        gate, tick = int(named["N"]), int(named["T"])
    except (KeyError, ValueError):
        raise ValueError(f"malformed gate event {event.fields}") from None
    if not 1 <= gate <= gates or tick < 0:
        raise ValueError(f"gate event out of range: gate {gate}, tick {tick}")
    return GateCrossing(gate, tick)
