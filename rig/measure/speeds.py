"""Ball speeds from the light gates' tick counts.

Geometry: gate i sits at distance x_i from the impact point, gate 1 farthest (x1 > x2 > x3).
Inbound the ball breaks 1, 2, 3; after the impact it comes back through 3, 2, 1 (as far as it
gets). Each pair of gates gives an average speed over its spacing; tick differences are taken
modulo the counter's width, so a counter wrap mid-shot changes nothing.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from rig.core.devices import GateConfig, GateCrossing
from rig.core.errors import RigError


class ShotDataError(RigError):
    """The gate events of a shot cannot give a speed; the message says why."""


@dataclass(frozen=True)
class GatePasses:
    """Crossings sorted into the inbound pass and the rebound pass, by gate number."""

    inbound: dict[int, GateCrossing]
    rebound: dict[int, GateCrossing]
    extra: tuple[GateCrossing, ...]  # crossings beyond two per gate (doubled triggers)


DOUBLE_TRIGGER_S = 2e-3  # a second break of the same beam this soon is the same ball pass


def split_passes(
    crossings: Iterable[GateCrossing], cfg: GateConfig, double_within_s: float = DOUBLE_TRIGGER_S
) -> GatePasses:
    """Sort crossings into passes by time: gate numbers rise inbound (1, 2, 3), then fall.

    Events are put in counter order first (they may arrive out of order), a repeat of the same
    gate within `double_within_s` is set aside as a doubled trigger, and a missed gate simply
    leaves a hole in its pass.
    """
    items = list(crossings)
    for c in items:
        if not 1 <= c.gate <= cfg.gates:
            raise ShotDataError(f"crossing at gate {c.gate}, but the rig has gates 1..{cfg.gates}")
    if not items:
        return GatePasses({}, {}, ())
    origin = items[0]
    # Events are at most milliseconds apart, far less than half a counter wrap: order them by
    # signed distance from the first one.
    half = cfg.modulus // 2

    def offset(c: GateCrossing) -> int:
        return (c.tick - origin.tick + half) % cfg.modulus - half

    ordered = sorted(items, key=offset)
    kept: list[GateCrossing] = []
    extra: list[GateCrossing] = []
    for c in ordered:
        last_same = next((k for k in reversed(kept) if k.gate == c.gate), None)
        if last_same is not None and elapsed_s(last_same, c, cfg) < double_within_s:
            extra.append(c)
        else:
            kept.append(c)
    inbound: dict[int, GateCrossing] = {}
    rebound: dict[int, GateCrossing] = {}
    k = 0
    while k < len(kept) and (not inbound or kept[k].gate > max(inbound)):
        inbound[kept[k].gate] = kept[k]
        k += 1
    for c in kept[k:]:
        if c.gate in rebound or (rebound and c.gate > min(rebound)):
            extra.append(c)  # not part of a falling sequence: a stray trigger
        else:
            rebound[c.gate] = c
    return GatePasses(inbound, rebound, tuple(extra))


def elapsed_s(earlier: GateCrossing, later: GateCrossing, cfg: GateConfig) -> float:
    """Seconds from one crossing to a later one, across at most one counter wrap."""
    return ((later.tick - earlier.tick) % cfg.modulus) * cfg.tick_s


def pair_speed(a: GateCrossing, b: GateCrossing, distance_m: float, cfg: GateConfig) -> float:
    """Average speed between two crossings a distance apart; refuses equal timestamps."""
    dt = elapsed_s(a, b, cfg)
    if dt <= 0.0:
        raise ShotDataError(f"gates {a.gate} and {b.gate} report the same tick {a.tick}: no speed")
    return distance_m / dt


@dataclass(frozen=True)
class ShotSpeeds:
    """Pair speeds of one shot, m/s; None where a pass did not reach both gates."""

    inbound_far: float | None  # gates 1 -> 2
    inbound_near: float | None  # gates 2 -> 3
    rebound_near: float | None  # gates 3 -> 2
    rebound_far: float | None  # gates 2 -> 1
    inbound_span: float | None = None  # gates 1 -> 3, used only when gate 2 missed the ball
    rebound_span: float | None = None  # gates 3 -> 1, likewise

    @property
    def inbound(self) -> float | None:
        """Inbound speed at the bat: the pair nearest the impact, else the widest pair left."""
        return _first(self.inbound_near, self.inbound_span, self.inbound_far)

    @property
    def rebound(self) -> float | None:
        """Rebound speed off the bat: the pair nearest the impact, else the widest pair left."""
        return _first(self.rebound_near, self.rebound_span, self.rebound_far)


def _first(*values: float | None) -> float | None:
    return next((v for v in values if v is not None), None)


def shot_speeds(passes: GatePasses, positions_m: Sequence[float], cfg: GateConfig) -> ShotSpeeds:
    """Speeds over each gate pair, from the passes and the gates' distances from the impact."""
    if len(positions_m) != 3 or not positions_m[0] > positions_m[1] > positions_m[2] >= 0.0:
        raise ShotDataError(f"gate positions {list(positions_m)} must be three, farthest first, >= 0")
    x1, x2, x3 = positions_m

    def speed(p: dict[int, GateCrossing], g_from: int, g_to: int, dist: float) -> float | None:
        if g_from in p and g_to in p:
            return pair_speed(p[g_from], p[g_to], dist, cfg)
        return None

    return ShotSpeeds(
        inbound_far=speed(passes.inbound, 1, 2, x1 - x2),
        inbound_near=speed(passes.inbound, 2, 3, x2 - x3),
        rebound_near=speed(passes.rebound, 3, 2, x2 - x3),
        rebound_far=speed(passes.rebound, 2, 1, x1 - x2),
        inbound_span=speed(passes.inbound, 1, 3, x1 - x3) if 2 not in passes.inbound else None,
        rebound_span=speed(passes.rebound, 3, 1, x1 - x3) if 2 not in passes.rebound else None,
    )
