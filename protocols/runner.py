"""Runs a certification procedure against device interfaces, emitting events, deciding the verdict.

The runner is restartable: its progress is a fold of the recorded events (protocols.state), so
`run()` on a resumed event list continues at the next unfired shot. A shot whose intent was
recorded but whose outcome was not (a crash between FIRE and the record) is marked lost, never
fired again.
"""

from __future__ import annotations

import contextlib
import platform
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from protocols import evaluate
from protocols.procedure import Procedure
from protocols.shot import ShotFailed, ShotRecord, fire_shot, prepare
from protocols.state import RunState, fold
from rig import __version__
from rig.core import events as ev
from rig.core.bat import PIVOT_FROM_KNOB_IN, BatSpec
from rig.core.config import RigConfig
from rig.core.devices import Cannon, CannonState, Clamp, GateConfig, GateCrossing, Gates
from rig.core.errors import ConfigError, DeviceError, DeviceGone, RigError, SafetyRefusal
from rig.core.events import RunEvent
from rig.core.units import INCH
from rig.measure.moi import entered_budget, pendulum_moi
from rig.measure.realtime import InboundKnown, ReboundKnown, ShotTracker


class Operator(Protocol):
    """Answers the operator prompts (ring check, ball replacement)."""

    def ask(self, prompt_id: str, text: str) -> bool: ...


@dataclass
class ScriptedOperator:
    """An operator for scripted runs: answers every prompt the same way, recorded as such."""

    answer: bool = True
    who: str = "script"

    def ask(self, prompt_id: str, text: str) -> bool:
        """Return the scripted answer."""
        return self.answer


class RunControl:
    """Commands from a UI to a running procedure: pause, resume, abort (thread-safe)."""

    def __init__(self) -> None:
        self._go = threading.Event()
        self._go.set()
        self._abort = threading.Event()
        self.reason = "aborted by the operator"
        self.settled = False  # the run's outcome is being recorded: nothing is left to stop

    def pause(self) -> None:
        """Hold before the next shot."""
        self._go.clear()

    def resume(self) -> None:
        """Go on after a pause."""
        self._go.set()

    def abort(self, reason: str = "aborted by the operator") -> None:
        """Stop before the next shot (the one in progress is recorded first); the run stays resumable."""
        if not self._abort.is_set():
            self.reason = reason
        self._abort.set()
        self._go.set()

    @property
    def paused(self) -> bool:
        """Whether a pause is in force."""
        return not self._go.is_set()

    @property
    def aborted(self) -> bool:
        """Whether an abort was asked for."""
        return self._abort.is_set()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block while paused; True once free to go on."""
        return self._go.wait(timeout_s)


class RunAborted(RigError):
    """The run cannot go on; the reason is recorded and the run can be resumed after a fix."""


class BudgetExceeded(RunAborted):
    """More invalid shots than the procedure allows since the rig was last checked."""


def location_problem(bat: BatSpec, loc_in: float) -> str | None:
    """Why the rig cannot hit the bat `loc_in` inches from the tip, or None if it can."""
    q_mm = bat.impact_from_pivot_m(loc_in) * 1000.0
    if not 0.0 < loc_in < bat.length_in - PIVOT_FROM_KNOB_IN:
        return f"scan location {loc_in:g} in from the tip is not on the bat beyond the pivot"
    if not 100.0 <= q_mm <= 900.0:
        return f"scan location {loc_in:g} in needs the stage at {q_mm:.0f} mm (range 100-900 mm)"
    return None


def dry_run(p: Procedure, bat: BatSpec, config: RigConfig) -> list[str]:
    """Everything in the procedure the rig or the bat cannot do, found before the cannon is armed."""
    problems: list[str] = []
    lo, hi = config.aim.speed_m_s[0], config.aim.speed_m_s[-1]
    for speed in (p.target_speed_m_s - p.speed_tolerance_m_s, p.target_speed_m_s + p.speed_tolerance_m_s):
        if not lo <= speed <= hi:
            problems.append(
                f"target speed {speed:.2f} m/s is outside the aim calibration ({lo:g}-{hi:g} m/s)"
            )
    problems += [m for m in (location_problem(bat, loc) for loc in p.scan.locations_in()) if m]
    if p.moi.source == "entered" and bat.moi_kgm2 is None:
        problems.append("procedure wants the MOI entered, but the bat file has no moi_kgm2")
    if p.moi.source == "entered" and bat.moi_kgm2 is not None and bat.moi_u_kgm2 is None:
        problems.append("an entered MOI needs its standard uncertainty: add moi_u_kgm2 to the bat file")
    if p.moi.source == "pendulum" and bat.balance_point_in is None:
        problems.append("the pendulum MOI needs balance_point_in in the bat file")
    if p.hits.valid_hits > p.ball.replace_after_hits * 10:
        problems.append("more valid hits than ten balls allow")
    return problems


class Runner:
    """Executes one procedure for one bat; every persisted event goes to `emit` before it goes on."""

    def __init__(
        self,
        procedure: Procedure,
        bat: BatSpec,
        config: RigConfig,
        cannon: Cannon,
        gates: Gates,
        clamp: Clamp,
        emit: Callable[[RunEvent], None],
        operator: Operator | None = None,
        history: list[RunEvent] | None = None,
        drain_traffic: Callable[[], list[dict[str, Any]]] | None = None,
        control: RunControl | None = None,
        confirm_fire: bool = False,
        review_shots: bool = False,
        rig_check: dict[str, str] | None = None,
    ) -> None:
        self.p, self.bat, self.config = procedure, bat, config
        self.cannon, self.gates, self.clamp = cannon, gates, clamp
        self._emit = emit
        self.operator = operator or ScriptedOperator()
        self.history = list(history or [])
        self.state: RunState = fold(self.history)
        self.drain_traffic = drain_traffic or (lambda: [])
        self.gate_config: GateConfig | None = None
        self.control = control or RunControl()
        self.confirm_fire = confirm_fire  # the operator confirms every shot (the UI's fire key)
        self.review_shots = review_shots  # the operator may reject a valid shot (never accept an invalid one)
        self.rig_check = rig_check  # {who, why}: the rig was checked, the re-shoot budget starts again
        # Where this session has put the stage (inches from the tip); None until a MOVE is confirmed.
        # Never taken from the record: a resumed session, a new port or a recovered device may be
        # anywhere, so every shot commands its own location unless this session put it there.
        self._stage_at: float | None = None

    def flush_traffic(self) -> None:
        """Record device traffic not yet attached to a shot (e.g. before an interruption)."""
        chunks = self.drain_traffic()
        if chunks:
            self.emit(ev.TRAFFIC, index=None, chunks=chunks)

    # -- events -----------------------------------------------------------------------------
    def emit(self, kind: str | RunEvent, **data: Any) -> None:
        """Record a fact (a typed event, or its kind and payload) and update the run state from it."""
        event = kind if isinstance(kind, RunEvent) else ev.event(kind, **data)
        self._emit(event)
        if event.persisted:
            self.history.append(event)
            self.state.apply(event)  # the same fold, one event on

    # -- the procedure ----------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        """Run (or resume) to the verdict; returns the RunFinished payload."""
        if self.state.finished:
            return dict(self.state.verdict or {})
        if self.state.ended is not None:
            raise ConfigError("the run was ended without a verdict; start a new one", source="resume")
        problems = dry_run(self.p, self.bat, self.config)
        if problems:
            raise ConfigError("; ".join(problems), source="dry run")
        self._start()
        self._check_budget()
        self._hold()
        self._check_environment()
        self._hold()
        first = self._next_location()
        self.gate_config = prepare(self.cannon, self.gates, self.clamp, self._q(first))
        self._stage_at = first
        self.emit(ev.LOCATION_SET, from_barrel_end_in=first, impact_from_pivot_m=self._q(first))
        self._resolve_pending()
        if self.state.moi is None:
            self._measure_moi()
        self._scan()
        if self.state.best_location_in is None:
            self._choose_location()
        best = self.state.best_location_in
        assert best is not None
        while len(self.state.valid_shots("valid", best)) < self.p.hits.valid_hits:
            self._shoot(best, "valid")
        self._hold()
        verdict = evaluate.verdict(self.p, self.bat, self.state, self.config)
        self.flush_traffic()
        self.emit(ev.RUN_FINISHED, **verdict)
        return verdict

    def _next_location(self) -> float:
        """Where the next shot goes: the first scan location short of hits, or the chosen one."""
        if self.state.best_location_in is not None:
            return self.state.best_location_in
        for loc in self.state.scan_locations(self.p.scan.locations_in()):
            if len(self.state.valid_shots("scan", loc)) < self.p.scan.hits_per_location:
                return loc
        return self.p.scan.from_in

    def _check_budget(self) -> None:
        """Record the operator's rig check (budget starts again); stop at once if still over budget."""
        if self.rig_check is not None:
            self.emit(
                ev.RIG_CHECKED,
                who=self.rig_check["who"],
                why=self.rig_check["why"],
                invalid_shots_before=self.state.invalid_count,
            )
        self._check_reshoots()

    def _check_reshoots(self) -> None:
        limit = self.p.hits.max_reshoots
        if self.state.invalid_since_check > limit:
            since = "since the last rig check" if self.state.invalid_at_last_check else "in this run"
            raise BudgetExceeded(f"more than {limit} invalid shots {since}: check the rig")

    def _start(self) -> None:
        if not self.state.started:
            calibration = evaluate.run_calibration(self.p, self.config)
            self.emit(
                ev.RUN_STARTED,
                procedure=self.p.model_dump(mode="json"),
                bat=self.bat.model_dump(mode="json"),
                rig=self.config.model_dump(mode="json"),
                software={"rig": __version__, "python": platform.python_version()},
                **({"calibration": calibration} if calibration else {}),
            )
        else:
            self.emit(ev.RUN_RESUMED, shots_so_far=len(self.state.shots))
        if self.cannon.status().state is CannonState.FAULT:
            self.cannon.reset()  # a fault left by the previous session; the tank is vented

    def _check_environment(self) -> None:
        env = self.cannon.environment()
        lim = self.p.environment
        ok_t = lim.temperature_c[0] <= env.temperature_c <= lim.temperature_c[1]
        ok_h = lim.humidity_pct[0] <= env.humidity_pct <= lim.humidity_pct[1]
        self.emit(
            ev.ENVIRONMENT_CHECKED,
            temperature_c=env.temperature_c,
            humidity_pct=env.humidity_pct,
            ok=ok_t and ok_h,
        )
        if not (ok_t and ok_h):
            raise RunAborted(
                f"lab conditions {env.temperature_c:.1f} C, {env.humidity_pct:.0f} % RH outside the "
                f"procedure's {lim.temperature_c} C, {lim.humidity_pct} % RH"
            )

    def _resolve_pending(self) -> None:
        pending = self.state.pending
        if pending is None:
            return
        reason = (
            "the run stopped after this shot was requested and before its outcome was recorded; "
            "it may have been fired, so it is not fired again"
        )
        self.emit(ev.SHOT_LOST, index=pending.index, reason=reason)

    def _measure_moi(self) -> None:
        """The MOI and its derived u: entered with its stated u, or timed on the pendulum (F2398)."""
        if self.p.moi.source == "entered":
            if self.bat.moi_kgm2 is None or self.bat.moi_u_kgm2 is None:
                lacks = "moi_kgm2" if self.bat.moi_kgm2 is None else "moi_u_kgm2 (the MOI's standard u)"
                raise ConfigError(f"procedure wants the MOI entered, but the bat file lacks {lacks}")
            found = entered_budget(self.bat.moi_kgm2, self.bat.moi_u_kgm2)
            self.emit(ev.MOI_MEASURED, **found.as_dict())
            return
        if self.bat.balance_point_in is None:
            raise ConfigError("the pendulum MOI needs the bat's balance_point_in in the bat file")
        timings = [self.clamp.measure_period(self.p.moi.cycles) for _ in range(self.p.moi.repeats)]
        balance_m = self.bat.balance_point_in * INCH
        reading, found = pendulum_moi(timings, self.bat.mass_kg, balance_m, self.config.pendulum)
        self.emit(
            ev.MOI_MEASURED,
            **found.as_dict(),
            period_s=sum(reading.periods_s) / len(reading.periods_s),
            periods_s=list(reading.periods_s),
            amplitude_deg=reading.amplitude_deg,
            cycles=reading.cycles,
        )

    def _scan_means(self) -> dict[float, float]:
        means: dict[float, float] = {}
        for loc in sorted(self.state.scan_locations(self.p.scan.locations_in())):
            vals = [s.metric for s in self.state.valid_shots("scan", loc) if s.metric is not None]
            if vals:
                means[loc] = sum(vals) / len(vals)
        return means

    def _scan(self) -> None:
        """Shoot the scan; while its maximum sits at an edge, extend it by one step (recorded)."""
        while True:
            for loc in self.state.scan_locations(self.p.scan.locations_in()):
                while len(self.state.valid_shots("scan", loc)) < self.p.scan.hits_per_location:
                    self._shoot(loc, "scan")
            if self.state.best_location_in is not None:
                return
            step = self._extension()
            if step is None:
                return
            loc, reason = step
            self.emit(
                ev.SCAN_EXTENDED, from_barrel_end_in=loc, impact_from_pivot_m=self._q(loc), reason=reason
            )

    def _extension(self) -> tuple[float, str] | None:
        """The next location beyond the scan's edge if the maximum is there and the rig may go on."""
        means = self._scan_means()
        best = max(means, key=lambda k: means[k])
        planned = self.p.scan.locations_in()
        reach = planned[0] - self.p.scan.extend_in - 1e-9, planned[-1] + self.p.scan.extend_in + 1e-9
        for sign, side in ((-1.0, "tip"), (1.0, "handle")):
            if any(sign * (x - best) > 0 for x in means):
                continue  # a lower mean on this side already
            nxt = round(best + sign * self.p.scan.step_in, 6)
            if reach[0] <= nxt <= reach[1] and location_problem(self.bat, nxt) is None:
                return nxt, (
                    f"the highest mean {self.p.standard.value} so far ({means[best]:.4f}) is at {best:g} in, "
                    f"the scan's edge towards the {side}: the maximum is not bracketed yet"
                )
        return None  # bracketed, or the procedure and the bat allow no further step

    def _choose_location(self) -> None:
        means = self._scan_means()
        best = max(means, key=lambda k: means[k])
        bracketed = any(x < best for x in means) and any(x > best for x in means)
        extra: dict[str, Any] = {"bracketed": bracketed}
        if not bracketed:
            text = (
                f"The highest mean {self.p.standard.value} ({means[best]:.4f}) is at {best:g} in from the "
                f"tip, the edge of the scan (extended as far as the procedure and the bat allow): the "
                f"maximum is not bracketed. Certify at {best:g} in anyway?"
            )
            if not self._prompt("edge-location", text):
                raise RunAborted(
                    f"the location of maximum performance is not bracketed (highest mean at {best:g} in, "
                    "the scan's edge): widen the procedure's scan or scan.extend_in"
                )
            extra["accepted_by"] = getattr(self.operator, "who", "operator")
        self.emit(
            ev.LOCATION_CHOSEN,
            from_barrel_end_in=best,
            mean_metric=means[best],
            scan={str(k): v for k, v in means.items()},
            **extra,
        )

    # -- one shot ---------------------------------------------------------------------------
    def _q(self, loc_in: float) -> float:
        return self.bat.impact_from_pivot_m(loc_in)

    def _prompt(self, prompt_id: str, text: str) -> bool:
        self.emit(ev.OPERATOR_PROMPTED, prompt_id=prompt_id, text=text)
        answer = self.operator.ask(prompt_id, text)
        self.emit(
            ev.OPERATOR_ANSWERED,
            prompt_id=prompt_id,
            answer=answer,
            who=getattr(self.operator, "who", "operator"),
        )
        return answer

    def _hold(self) -> None:
        """Honour pause and abort between shots."""
        if self.control.paused:
            self.emit(ev.RUN_PAUSED)
            self.control.wait()
            if not self.control.aborted:
                self.emit(ev.RUN_CONTINUED)
        if self.control.aborted:
            raise RunAborted(self.control.reason)

    def _shoot(self, loc_in: float, purpose: str) -> None:
        self._hold()
        self._check_reshoots()
        if self.state.ball_hits >= self.p.ball.replace_after_hits:
            if not self._prompt(
                "ball",
                f"Replace the ball (ball {self.state.ball_number} has {self.state.ball_hits} hits). Done?",
            ):
                raise RunAborted("ball not replaced")
            self.emit(ev.BALL_REPLACED, ball_number=self.state.ball_number + 1)
        index = len(self.state.shots) + 1
        if self.p.ring_check and not self._prompt(
            f"ring-before-{index}", "Ring check: does the ring pass over the whole bat?"
        ):
            self._fail_ring(index)
        if self._stage_at != loc_in:
            self._move(loc_in)
        q = self._q(loc_in)
        config = self.config.model_copy(update={"impact_from_pivot_m": q})
        aim_speed = self.p.target_speed_m_s / self.state.aim_factor
        try:  # before the shot is requested: an aim the cannon cannot give stops the run, nothing fired
            self.config.aim.pressure_for(aim_speed)
        except ConfigError as exc:
            raise RunAborted(
                f"{exc}: the measured speeds are far from the aim (gate positions in the rig config wrong?)"
            ) from exc
        if self.confirm_fire and not self._prompt(
            f"fire-{index}", f"Fire shot {index} ({purpose}) at {loc_in:g} in from the tip?"
        ):
            raise RunAborted(f"the operator declined to fire shot {index}")
        self._hold()
        self.emit(
            ev.SHOT_REQUESTED,
            index=index,
            purpose=purpose,
            location_in=loc_in,
            target_speed_m_s=self.p.target_speed_m_s,
            aim_speed_m_s=aim_speed,
        )
        try:
            self._fire_and_record(config, aim_speed, index)
        except BaseException as exc:
            self._lose_unresolved(index, exc)
            raise
        if self.state.pending is None and self.state.shots[-1].lost:
            return
        self._after_shot(index)

    def _move(self, loc_in: float) -> None:
        """Command the stage to `loc_in` and wait for it there; only then is the position known."""
        self._stage_at = None
        q = self._q(loc_in)
        self.clamp.move_to(q * 1000.0)
        self._stage_at = loc_in
        self.emit(ev.LOCATION_SET, from_barrel_end_in=loc_in, impact_from_pivot_m=q)

    def _lose_unresolved(self, index: int, exc: BaseException) -> None:
        """Anything that stops a shot before its outcome is recorded marks it lost (never fired again)."""
        pending = self.state.pending
        if pending is None or pending.index != index:
            return
        with contextlib.suppress(Exception):
            self.emit(ev.TRAFFIC, index=index, chunks=self.drain_traffic())
            self.emit(
                ev.SHOT_LOST,
                index=index,
                reason=f"the run stopped during this shot ({type(exc).__name__}: {exc}); "
                "it may have been fired, so it is not fired again",
            )

    def _fire_and_record(self, config: RigConfig, aim_speed: float, index: int) -> None:
        """Fire the requested shot and record its raw data, then its outcome (measured, rejected, lost)."""
        try:
            record, failure = self._fire(config, aim_speed, index)
        except DeviceError as exc:
            self._stage_at = None  # a device may have been reset or reopened: command the stage again
            self.emit(ev.TRAFFIC, index=index, chunks=self.drain_traffic())
            self.emit(ev.SHOT_LOST, index=index, reason=f"{type(exc).__name__}: {exc}")
            self._recover_or_abort(exc)
            return
        self.emit(
            ev.SHOT_FIRED,
            index=index,
            ball_number=self.state.ball_number,
            **(record.as_dict() if record else {"crossings": []}),
        )
        self.emit(ev.TRAFFIC, index=index, chunks=self.drain_traffic())
        if record is None:
            self.emit(ev.SHOT_LOST, index=index, reason=failure)
            return
        result = evaluate.shot(record, self.p, self.bat, self.state, failure, self.config)
        self.emit(ev.SHOT_MEASURED if result["valid"] else ev.SHOT_REJECTED, index=index, **result)

    def _after_shot(self, index: int) -> None:
        """The operator's review and the ring check after a recorded shot."""
        shot = self.state.shots[-1]
        if shot.valid and self.review_shots:
            metric = f"{self.p.standard.value} {shot.metric:.4f}"
            if not self._prompt(f"review-{index}", f"Accept shot {index} ({metric})? n rejects it: re-shoot"):
                self.emit(
                    ev.SHOT_OVERRULED,
                    index=index,
                    reason="rejected by the operator on review",
                    who=getattr(self.operator, "who", "operator"),
                )
        if self.p.ring_check and not self._prompt(
            f"ring-after-{index}", "Ring check after the hit: does the ring still pass?"
        ):
            self._fail_ring(index)

    def _live(self, index: int) -> Callable[[GateCrossing], None]:
        """Feed each gate event to a tracker; speeds go out as live events as soon as known."""
        assert self.gate_config is not None
        tracker = ShotTracker(self.gate_config, self.config.gates.positions_m)

        def on_crossing(c: GateCrossing) -> None:
            self.emit(ev.GATE_CROSSED, index=index, gate=c.gate, tick=c.tick, host_time_s=c.host_time_s)
            for update in tracker.add(c):
                if isinstance(update, InboundKnown):
                    self.emit(ev.INBOUND_MEASURED, index=index, speed_m_s=update.v)
                elif isinstance(update, ReboundKnown):
                    self.emit(ev.REBOUND_MEASURED, index=index, speed_m_s=update.v)

        return on_crossing

    def _fire(self, config: RigConfig, aim_speed: float, index: int) -> tuple[ShotRecord | None, str]:
        assert self.gate_config is not None
        try:
            rec = fire_shot(
                self.cannon,
                self.gates,
                self.clamp,
                config,
                aim_speed,
                self.gate_config,
                on_crossing=self._live(index),
            )
            return rec, ""
        except ShotFailed as exc:
            return exc.record, str(exc)

    def _recover_or_abort(self, exc: DeviceError) -> None:
        """After a shot lost to a device error: make the cannon safe and go on, or stop the run.

        The lost shot is never fired again (it is recorded as lost); an open interlock or a vanished
        device stops the run, to be resumed once the operator has fixed it.
        """
        if isinstance(exc, SafetyRefusal | DeviceGone):
            raise RunAborted(f"shot not completed: {exc}") from exc
        try:
            state = self.cannon.status().state
            if state is CannonState.FAULT:
                self.cannon.reset()
            elif state is CannonState.ARMED:
                self.cannon.vent()
        except DeviceError as again:
            raise RunAborted(f"device failure: {exc}; then {again}") from exc

    def _fail_ring(self, index: int) -> None:
        verdict = {
            "verdict": ev.Verdict.FAIL,
            "reason": f"ring check failed at shot {index}: barrel deformed",
            "metric": self.p.standard.value,
            "limit": self.p.limit,
        }
        self.emit(ev.RUN_FINISHED, **verdict)
        raise RunAborted(verdict["reason"])
