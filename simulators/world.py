"""SimWorld: one simulated rig - virtual clock, shared physical state, the three devices, a shot.

Built from a Scene. The effects the scene turns on are inspected once here: their chained hooks
go into `hooks`, and slot-filling effects replace the default flight, collision, counter, recoil
sensor and lab sensors of `rig.simulators.physics`. A scene without effects therefore runs the closed
forms only, with the rigid-barrel collision solved once per distinct impact.
"""

from __future__ import annotations

import functools
import math
import random
import threading
from collections.abc import Callable
from typing import Any

from rig.core.devices import Interlocks
from rig.physics import CollisionParams
from rig.simulators.cannon import SimCannon
from rig.simulators.clamp import SimClamp
from rig.simulators.device import SimDevice
from rig.simulators.effects import CHAINED_HOOKS, Effect, overrides
from rig.simulators.effects.softening import BarrelSoftening
from rig.simulators.gates import SimGates
from rig.simulators.physics import (
    Collision,
    EnvironmentSensor,
    Flight,
    NominalEnvironment,
    RecoilSensor,
    RigidCollision,
    RigidTarget,
    RoundingTicks,
    StraightFlight,
    Ticks,
    drop_m,
    pendulum_period,
)
from rig.simulators.records import Crossing, Outgoing, ShotTruth, SimBall
from rig.simulators.scene import Scene
from rig.simulators.timeline import Schedule

RECOIL_REPORT_S = 0.01  # the encoder reports the peak angular speed this long after contact
FIRST_BALL = "ball-01"  # the ball in the breech until the host LOADs one


class SimWorld:
    """One simulated rig; devices opened on the same world share its state and clock."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.clock = 0.0  # virtual seconds since the world started
        self.rng = random.Random(scene.run_key())
        self.lock = threading.RLock()
        self.changed = threading.Condition(self.lock)  # notified whenever output is queued
        self._schedule = Schedule()
        # Each effect draws from its own stream, so adding one never shifts another's numbers; the
        # streams are the run's own (Scene.run_key): another bat or another hour draws other noise.
        run = scene.run_key()
        self.effects: tuple[Effect, ...] = tuple(
            spec.build(scene, random.Random(f"{run}/{i}/{spec.kind}"))
            for i, spec in enumerate(scene.effects)
            if spec.enabled
        )
        # each hook has its own signature (rig.simulators.effects.base.Effect): callers know which they call
        self.hooks: dict[str, tuple[Callable[..., Any], ...]] = {
            hook: tuple(getattr(e, hook) for e in self.effects if overrides(e, hook))
            for hook in CHAINED_HOOKS
        }
        # the effect in a slot is that slot's component (rig.simulators.physics: Flight, Collision, ...)
        slots: dict[str, Any] = {e.slot: e for e in self.effects if e.slot}
        self.flight: Flight = slots.get("flight") or StraightFlight()
        self.collision: Collision = slots.get("collision") or RigidCollision(scene.bat.moi_kgm2)
        if scene.target.rigid:  # a rigid target in the clamp: no bat, so no trampoline and no recoil
            self.collision = RigidTarget(scene.target.contact_factor)
        self.ticker: Ticks = slots.get("ticks") or RoundingTicks(scene.rig.tick_ns * 1e-9)
        self.recoil_sensor: RecoilSensor | None = None if scene.target.rigid else slots.get("recoil")
        self.lab: EnvironmentSensor = slots.get("environment") or NominalEnvironment()
        # a barrel that rolling softens (ABI), if the scene has one
        self.barrel = next((e for e in self.effects if isinstance(e, BarrelSoftening)), None)
        self.door = True
        self.estop = True
        self._pending_ilk: list[tuple[float, str, bool]] = []
        self.attempts = 0  # FIRE commands accepted (misfires included): the faults' shot number
        self.shots: list[ShotTruth] = []
        self.balls: dict[str, SimBall] = {}  # every ball fired or loaded, by id, with its hits so far
        self.ball_id = FIRST_BALL
        self.cannon = SimCannon(self)
        self.gates = SimGates(self)
        self.clamp = SimClamp(self)
        self.devices: dict[str, SimDevice] = {"cannon": self.cannon, "gates": self.gates, "clamp": self.clamp}
        # other front ends on this world (instrument twins): each is told every shot's beam breaks
        self.crossing_listeners: list[Callable[[list[Crossing], tuple[tuple[int, int], ...], int], None]] = []

    def roll(self, depth_in: float, passes: int) -> float:
        """Roll the bat's barrel (accelerated break-in): it softens, its hoop frequency falls and the
        collision is told; returns the new hoop frequency, Hz. ValueError without a softening barrel."""
        with self.lock:
            if self.barrel is None:
                raise ValueError("this scene's barrel does not soften (no barrel_softening effect)")
            self.barrel.roll(depth_in, passes)
            tell = getattr(self.collision, "set_hoop_hz", None)
            if tell is not None:
                tell(self.barrel.hoop_hz)
            return self.barrel.hoop_hz

    # -- virtual time -----------------------------------------------------------------------
    def at(self, time_s: float, apply: Callable[[], None], tag: str | None = None) -> None:
        """Apply a state change when the clock reaches `time_s` (at once if that is now)."""
        if time_s <= self.clock:
            apply()
        else:
            self._schedule.at(time_s, apply, tag)

    def advance_to(self, time_s: float) -> None:
        """Move the clock forward to `time_s`, applying scheduled changes in order."""
        with self.lock:
            if time_s <= self.clock:
                return
            for when, apply in self._schedule.due(time_s):
                self.clock = max(self.clock, when)
                apply()
            self.clock = time_s

    def advance(self, seconds: float) -> None:
        """Let `seconds` of virtual time pass (for tests and idle hosts)."""
        self.advance_to(self.clock + seconds)

    def cancel(self, tag: str) -> None:
        """Withdraw pending changes and not-yet-happened messages tagged `tag`."""
        self._schedule.cancel(tag)
        for device in self.devices.values():
            device.out.cancel(tag, self.clock)

    # -- interlocks -------------------------------------------------------------------------
    def interlocks(self) -> Interlocks:
        """The interlock loop now (the clamp's lock sensor is wired into it)."""
        return Interlocks(door=self.door, clamp=self.clamp.locked, estop=self.estop)

    def interlocks_at(self, time_s: float) -> Interlocks:
        """The interlock loop as it will be at `time_s`, given the changes already scheduled."""
        state = {"door": self.door, "clamp": self.clamp.locked, "estop": self.estop}
        for when, name, closed in sorted(self._pending_ilk):
            if self.clock < when <= time_s:
                state[name] = closed
        return Interlocks(**state)

    def set_interlock(self, name: str, closed: bool, at: float | None = None) -> None:
        """Open or close 'door', 'estop' (or, from the clamp, 'clamp') now, or close it at `at`."""
        with self.lock:
            if name not in ("door", "estop", "clamp"):
                raise ValueError(f"no interlock {name!r}: door, estop or clamp")
            if at is not None and at > self.clock:
                if not closed:
                    raise ValueError("only closing can be scheduled; open an interlock now")
                self._pending_ilk.append((at, name, closed))
                self.cannon.interlocks_changed(self.interlocks_at(at), at, tag=f"ilk-{name}")
                self.at(at, lambda: self._apply_interlock(name, closed, at), tag=f"ilk-{name}")
            else:
                self._apply_interlock(name, closed, None)
                self.cannon.interlocks_changed(self.interlocks(), None)
            self.changed.notify_all()

    def cancel_interlock(self, name: str) -> None:
        """Withdraw a scheduled change of interlock `name` (e.g. a grip released before it locked)."""
        self.cancel(f"ilk-{name}")
        self._pending_ilk = [p for p in self._pending_ilk if p[1] != name]

    def _apply_interlock(self, name: str, closed: bool, scheduled: float | None) -> None:
        if scheduled is not None:
            self._pending_ilk.remove((scheduled, name, closed))
        if name == "clamp":
            self.clamp.locked = closed
        else:
            setattr(self, name, closed)

    # -- hooks ------------------------------------------------------------------------------
    def filter_outgoing(self, message: Outgoing) -> bytes | None:
        """Pass a message through the link faults; None if it is lost."""
        data: bytes | None = message.data
        for hook in self.hooks["outgoing"]:
            if data is None:
                return None
            data = hook(Outgoing(message.device, message.kind, message.name, message.shot, data))
        return data

    def misfires(self, shot: int) -> bool:
        """True if a misfire fault strikes this FIRE."""
        return any([hook(shot) for hook in self.hooks["misfire"]])

    def after_arm(self, shot: int) -> None:
        """Let interlock faults act once ARM is accepted."""
        for hook in self.hooks["after_arm"]:
            hook(self, shot)

    def after_shot(self, shot: int) -> None:
        """Let unplug faults cut a device off among the shot's messages."""
        for name, device in self.devices.items():
            for hook in self.hooks["unplug_after"]:
                count = hook(name, shot)
                if count is not None:
                    when = device.out.unplug_after(shot, count, self.clock)
                    self.at(when, functools.partial(setattr, device, "unplugged", True), tag=f"unplug-{name}")
                    break

    # -- balls ------------------------------------------------------------------------------
    def load_ball(self, ball_id: str) -> SimBall:
        """Put ball `ball_id` in the breech: a ball seen before keeps its hits, a new one starts fresh."""
        self.ball_id = ball_id
        return self.ball(ball_id)

    def ball(self, ball_id: str) -> SimBall:
        """The ball `ball_id` as it is now; a new one draws its offsets from the lot's spread."""
        ball = self.balls.get(ball_id)
        if ball is None:
            lot = self.scene.lot
            c1 = k1 = 1.0
            if lot.c1_spread_rel or lot.k1_spread_rel:  # the spread costs nothing when the scene has none
                # balls a lab picks for one bat are not the next bat's: the draw is the bat's too
                rng = random.Random(f"{self.scene.seed}/{self.scene.bat.id}/ball/{ball_id}")
                c1 = max(0.5, 1.0 + rng.gauss(0.0, lot.c1_spread_rel))
                k1 = max(0.5, 1.0 + rng.gauss(0.0, lot.k1_spread_rel))
            ball = self.balls[ball_id] = SimBall(ball_id, 0, c1, k1)
        return ball

    def _hit_ball(self, ball: SimBall) -> CollisionParams:
        """`ball`'s constants for this hit (its own offsets on the lot's ball); its count goes up by one."""
        params = self.scene.ball
        if ball.c1_scale != 1.0 or ball.k1_scale != 1.0:
            params = params.model_copy(
                update={"c1": params.c1 * ball.c1_scale, "k1": params.k1 * ball.k1_scale}
            )
        self.balls[ball.id] = SimBall(ball.id, ball.hits + 1, ball.c1_scale, ball.k1_scale)
        return params

    # -- physics ----------------------------------------------------------------------------
    def counter(self, ticks: int) -> int:
        """The gates' counter register after `ticks` ticks since the world started."""
        rig = self.scene.rig
        return (rig.counter_start + ticks) % (1 << rig.counter_bits)

    def swing_period(self) -> float:
        """The bat's true pendulum period on the pivot at the SWING amplitude, s."""
        bat, rig = self.scene.bat, self.scene.rig
        lever = bat.balance_point_m - rig.pivot_from_knob_m
        return pendulum_period(bat.moi_kgm2, bat.mass_kg, lever, math.radians(rig.swing_amplitude_deg))

    def fire(self, pressure_kpa: float, shot: int) -> ShotTruth:
        """Launch one ball now: gate crossings in and out, the impact, the recoil; queue the events."""
        scene, rig, bat = self.scene, self.scene.rig, self.scene.bat
        t0 = self.clock
        v0 = scene.cannon.muzzle_speed(pressure_kpa)
        for hook in self.hooks["launch_speed"]:
            v0 = hook(v0)
        t_exit = t0 + scene.cannon.launch_delay_s
        flight, muzzle = self.flight, rig.muzzle_m
        crossings = [
            Crossing(i + 1, t_exit + flight.time_to(muzzle - d, v0), True)
            for i, d in enumerate(rig.gate_positions_m)
        ]
        q = self.clamp.position_mm(t0) / 1000.0
        hit = scene.target.rigid or q <= bat.length_m - rig.pivot_from_knob_m
        v_in = flight.speed_at(muzzle, v0)
        t_impact = t_exit + flight.time_to(muzzle, v0)
        e_a = contact = v_out = 0.0
        omega = None
        ball = self.ball(self.ball_id)
        if hit:
            params = self._hit_ball(ball)
            for hook in self.hooks["ball_params"]:
                params = hook(params, t_impact, ball)
            e_a, contact = self.collision.collide(params, v_in, q)
            v_out = e_a * v_in
            t_leave = t_impact + contact
            for i in range(len(rig.gate_positions_m) - 1, -1, -1):
                dt = flight.time_to(rig.gate_positions_m[i], v_out)
                if drop_m(dt) > rig.beam_half_height_m:
                    break  # fallen below this beam, so below every farther one too
                crossings.append(Crossing(i + 1, t_leave + dt, False))
            if self.recoil_sensor is not None:
                omega = self.recoil_sensor.recoil(params.m1, q, v_in, v_out)
                self.clamp.report_recoil(omega, t_leave + RECOIL_REPORT_S, shot)
        for hook in self.hooks["crossings"]:
            crossings = hook(crossings, shot)
        ticks = tuple((x.gate, self.counter(self.ticker.latch(x.gate, x.time_s))) for x in crossings)
        self.gates.stream(crossings, ticks, shot)
        for listener in self.crossing_listeners:
            listener(crossings, ticks, shot)
        record = ShotTruth(
            number=len(self.shots) + 1,
            fire_time_s=t0,
            pressure_kpa=pressure_kpa,
            launch_speed=v0,
            impact_speed=v_in if hit else 0.0,
            impact_from_pivot_m=q,
            hit=hit,
            e_a=e_a,
            rebound_speed=v_out,
            contact_time_s=contact,
            impact_time_s=t_impact,
            recoil_rad_s=omega,
            crossings=tuple(crossings),
            ticks=ticks,
            ball_id=ball.id,
            ball_hits=ball.hits,
        )
        self.shots.append(record)
        return record
