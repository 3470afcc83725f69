"""Synthetic gate crossings of straight-line shots, and the typical shot of the brief."""

from __future__ import annotations

from rig.core.devices import GateConfig, GateCrossing
from rig.measure.uncertainty import ShotInputs

CFG = GateConfig(gates=3, tick_ns=100.0, bits=32)
POS = (0.75, 0.50, 0.25)
Q, MOI, BALL = 0.56, 0.19, 0.145
V_IN, V_OUT = 60.8, 11.0


def shot_ticks(
    v_in: float, v_out: float, start: int = 1000, cfg: GateConfig = CFG, pos: tuple[float, ...] = POS
) -> list[GateCrossing]:
    """Crossings of a drag-free shot in order 1, 2, 3 (in), 3, 2, 1 (out), ticks rounded."""
    times = [(pos[0] - x) / v_in for x in pos]
    t_hit = pos[0] / v_in
    times += [t_hit + x / v_out for x in (pos[2], pos[1], pos[0])]
    gates = [1, 2, 3, 3, 2, 1]
    return [
        GateCrossing(g, (start + round(t / cfg.tick_s)) % cfg.modulus)
        for g, t in zip(gates, times, strict=True)
    ]


def typical_shot(v_in: float = V_IN, v_out: float = V_OUT) -> ShotInputs:
    """The brief's typical shot: 60.8 in, 11 out, Q 0.56 m, I 0.19 kg m^2, gates 0.75/0.50/0.25 m."""
    return ShotInputs.ideal(v_in, v_out, POS, CFG.tick_s, Q, MOI, BALL)
