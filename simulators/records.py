"""Small immutable records the world, the devices and the effects pass between them."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Crossing:
    """The ball breaks a gate's beam: gate number (1-based), virtual time, inbound or rebound."""

    gate: int
    time_s: float
    inbound: bool


@dataclass(frozen=True)
class SimBall:
    """One physical ball of the scene's lot: its id, hits before this one, and its own offsets.

    `c1_scale` and `k1_scale` multiply the lot's nominal damping and stiffness: the ball-to-ball
    spread, drawn once per ball from the scene's seed and the ball's id.
    """

    id: str
    hits: int = 0
    c1_scale: float = 1.0
    k1_scale: float = 1.0


@dataclass(frozen=True)
class Outgoing:
    """One framed message a device is about to send; what link faults see and may spoil."""

    device: str  # "cannon", "gates" or "clamp"
    kind: str  # "reply" or "event"
    name: str  # the command's verb for a reply (also for an error reply), the event's name
    shot: int  # the shot it belongs to: events of shot n, or commands up to shot n's FIRE
    data: bytes


@dataclass(frozen=True)
class ShotTruth:
    """What really happened in one simulated shot: the ground truth a measurement is checked against.

    Not a measurement: the measured shot is rig.protocols.shot.ShotRecord (the raw record of a firing)
    and, folded from the log, rig.core.run_state.ShotEntry.
    """

    number: int  # 1-based count of balls fired
    fire_time_s: float
    pressure_kpa: float
    launch_speed: float  # at the muzzle, m/s
    impact_speed: float  # at the bat, m/s (0 if the ball missed the bat)
    impact_from_pivot_m: float
    hit: bool  # False if the stage put the impact point beyond the bat's tip
    e_a: float  # apparent COR: rebound speed / inbound speed at the bat
    rebound_speed: float  # just after contact, m/s
    contact_time_s: float
    impact_time_s: float
    recoil_rad_s: float | None  # the bat's angular speed after impact, if the recoil effect is on
    crossings: tuple[Crossing, ...]
    ticks: tuple[tuple[int, int], ...]  # (gate, counter value) as streamed, in time order
    ball_id: str = ""  # the ball fired (the id the host LOADed, else the world's first ball)
    ball_hits: int = 0  # hits that ball had taken before this shot
