"""Carries out a plan (rig.protocols.plan): run control, persistence, prompts, and the devices behind them.

The executor keeps the run's folded state current (every Record goes to `emit`, is recorded,
then folded), so a plan resumes from a killed run's record exactly. What the devices do is a
backend's business: `LiveRig` drives the real (or simulated) cannon, gates and clamp;
rig.protocols.dryrun's `CheckingRig` answers from checking fakes. A shot requested in this session
whose outcome is not recorded when anything stops the plan is recorded lost, never fired again.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any, Protocol, TypeVar, runtime_checkable

from rig.core import events as ev
from rig.core.config import RigConfig
from rig.core.devices import (
    BallLoader,
    BarrelCompression,
    Cannon,
    CannonState,
    Clamp,
    CompressionTester,
    Environment,
    GateConfig,
    GateCrossing,
    Gates,
    PendulumPeriod,
)
from rig.core.errors import ConfigError, DeviceError, DeviceGone, SafetyRefusal
from rig.core.events import RunEvent
from rig.core.outcomes import RunVerdict, ShotOutcome
from rig.core.run_phase import refuse, shot_refuse
from rig.measure.realtime import InboundKnown, ReboundKnown, ShotTracker
from rig.protocols import evaluate
from rig.protocols.control import (
    Answer,
    Operator,
    PlanError,
    Rolling,
    RollingOperator,
    RunAborted,
    RunControl,
    ScriptedOperator,
)
from rig.protocols.plan import (
    Ask,
    AskRolling,
    Checkpoint,
    ClearFault,
    Decide,
    DecideStage,
    Evaluate,
    Fire,
    Fired,
    MeasureCompression,
    Move,
    Msg,
    Plan,
    PlanContext,
    Prepare,
    Problem,
    ReadEnvironment,
    Record,
    TimePendulum,
)
from rig.protocols.shot import ShotFailed, fire_shot, prepare
from rig.protocols.state import RunState, fold

T = TypeVar("T")
Traffic = Callable[[], list[dict[str, Any]]]


class Backend(Protocol):
    """What the devices do for a plan (real devices, or checking fakes in a dry run)."""

    def clear_fault(self) -> None: ...
    def environment(self) -> Environment: ...
    def time_pendulum(self, cycles: int) -> PendulumPeriod: ...
    def prepare(self, impact_from_pivot_m: float) -> GateConfig: ...
    def move(self, impact_from_pivot_m: float) -> None: ...
    def fire(
        self,
        config: RigConfig,
        aim_speed_m_s: float,
        gates: GateConfig,
        live: Callable[[GateCrossing], None],
        ball: str | None = None,
    ) -> Fired: ...
    def recover(self, exc: DeviceError) -> None: ...
    def evaluate(self, ctx: PlanContext, fired: Fired) -> ShotOutcome: ...
    def decide(self, ctx: PlanContext) -> RunVerdict: ...
    def problem(self, text: str) -> None: ...


@runtime_checkable
class BreakInBackend(Protocol):
    """What an accelerated break-in needs besides: the compression tester, a stage's verdict."""

    def compression(self) -> BarrelCompression: ...
    def decide_stage(self, ctx: PlanContext, purpose: str, hoop_hz: float | None) -> RunVerdict: ...


class LiveRig:
    """The devices of a rig session: every message becomes device commands."""

    def __init__(
        self, cannon: Cannon, gates: Gates, clamp: Clamp, compression: CompressionTester | None = None
    ) -> None:
        self.cannon, self.gates, self.clamp = cannon, gates, clamp
        self.compression_tester = compression

    def compression(self) -> BarrelCompression:
        """The compression tester's reading; a rig without one stops the run (resumable)."""
        if self.compression_tester is None:
            raise RunAborted(
                "this rig has no barrel-compression tester: name one in the rig config "
                "([devices.compression], docs/instruments.md)"
            )
        return self.compression_tester.measure_compression()

    def decide_stage(self, ctx: PlanContext, purpose: str, hoop_hz: float | None) -> RunVerdict:
        """A break-in stage's verdict (rig.protocols.evaluate.stage_verdict)."""
        return evaluate.stage_verdict(ctx.procedure, ctx.bat, ctx.state, ctx.config, purpose, hoop_hz)

    def clear_fault(self) -> None:
        """Reset a fault left by the previous session (its tank is vented)."""
        if self.cannon.status().state is CannonState.FAULT:
            self.cannon.reset()

    def environment(self) -> Environment:
        """The cannon's lab sensor."""
        return self.cannon.environment()

    def time_pendulum(self, cycles: int) -> PendulumPeriod:
        """The clamp times the swings."""
        return self.clamp.measure_period(cycles)

    def prepare(self, impact_from_pivot_m: float) -> GateConfig:
        """Gates self-tested, bat locked, stage set."""
        return prepare(self.cannon, self.gates, self.clamp, impact_from_pivot_m)

    def move(self, impact_from_pivot_m: float) -> None:
        """Stage to the impact point (waits until it is there)."""
        self.clamp.move_to(impact_from_pivot_m * 1000.0)

    def fire(
        self,
        config: RigConfig,
        aim_speed_m_s: float,
        gates: GateConfig,
        live: Callable[[GateCrossing], None],
        ball: str | None = None,
    ) -> Fired:
        """Name the ball (to a cannon that takes it), aim, fire, collect; a shot without usable data
        still returns its raw record."""
        if ball is not None and isinstance(self.cannon, BallLoader):
            self.cannon.load_ball(ball)
        try:
            return Fired(fire_shot(self.cannon, self.gates, self.clamp, config, aim_speed_m_s, gates, live))
        except ShotFailed as exc:
            if exc.record is None:
                raise
            return Fired(exc.record, str(exc))

    def recover(self, exc: DeviceError) -> None:
        """After a shot lost to a device error: make the cannon safe, or stop the run.

        An open interlock or a vanished device stops the run, to be resumed once fixed.
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

    def evaluate(self, ctx: PlanContext, fired: Fired) -> ShotOutcome:
        """The shot's measurement (rig.protocols.evaluate; a context of its own kind measures its own)."""
        own = getattr(ctx, "evaluate_shot", None)
        if own is not None:
            measured: ShotOutcome = own(fired)
            return measured
        return evaluate.shot(fired.record, ctx.procedure, ctx.bat, ctx.state, fired.failure, ctx.config)

    def decide(self, ctx: PlanContext) -> RunVerdict:
        """The verdict (rig.protocols.evaluate; a context of its own kind decides its own)."""
        own = getattr(ctx, "decide_run", None)
        if own is not None:
            decided: RunVerdict = own()
            return decided
        return evaluate.verdict(ctx.procedure, ctx.bat, ctx.state, ctx.config)

    def problem(self, text: str) -> None:
        """A real run does not go on past a problem."""
        raise ConfigError(text, source="procedure")


class Executor:
    """Runs plans for one run: owns the state, run control, persistence and the stage's position."""

    def __init__(
        self,
        ctx: PlanContext,
        backend: Backend,
        emit: Callable[[RunEvent], None],
        operator: Operator | None = None,
        control: RunControl | None = None,
        drain_traffic: Traffic | None = None,
        max_messages: int | None = None,
    ) -> None:
        self.ctx, self.backend, self._emit = ctx, backend, emit
        self.max_messages = max_messages  # a rehearsal stops a plan that does not end
        self.operator = operator or ScriptedOperator()
        self.control = control or RunControl()
        self.drain_traffic = drain_traffic or (lambda: [])
        self.gate_config: GateConfig | None = None
        self._requested: int | None = None  # the shot this session requested and has not resolved
        # Where this session put the stage (inches from the tip); None until a move is confirmed.
        # Never taken from the record: a resumed session or a recovered device may be anywhere.
        self._stage_at: float | None = None

    @property
    def state(self) -> RunState:
        """The run's folded state."""
        return self.ctx.state

    def run(self, plan: Callable[[PlanContext], Plan[T]]) -> T:
        """Execute `plan` to its end; an error in a message is thrown into the plan where it yielded."""
        gen = plan(self.ctx)
        send: Callable[[Any], Msg] = gen.send
        value: Any = None
        count = 0
        while True:
            try:
                msg = send(value)
            except StopIteration as stop:
                result: T = stop.value
                return result
            except BaseException as exc:
                self._lose_requested(exc)
                raise
            count += 1
            if self.max_messages is not None and count > self.max_messages:
                gen.close()
                raise PlanError(f"the plan did not end within {self.max_messages} messages")
            try:
                value, send = self.handle(msg), gen.send
            except BaseException as exc:
                self._lose_requested(exc)  # before the plan sees it: a plan that catches it cannot leave
                value, send = exc, gen.throw  # the shot unresolved

    # -- persistence ------------------------------------------------------------------------
    def emit(self, event: RunEvent) -> None:
        """Record a fact (persisted ones are recorded first, if the run table takes them in the run's
        phase: PlanError if not), then fold it into the state."""
        refused = refuse(event.kind, self.state.phase) if event.persisted else None
        if refused is not None:
            raise PlanError(f"{refused}: the run table (rig.core.run_phase) refuses it")
        self._emit(event)
        if event.persisted:
            self.state.apply(event)
            if isinstance(event, ev.ShotRequested):
                self._requested = event.index

    def flush_traffic(self) -> None:
        """Record device traffic not yet attached to a shot (e.g. before an interruption)."""
        chunks = self.drain_traffic()
        if chunks:
            self.emit(ev.Traffic(index=None, chunks=chunks))

    def _lose_requested(self, exc: BaseException) -> None:
        """Anything that stops the plan between a shot's request and its outcome marks it lost."""
        pending = self.state.pending
        if self._requested is None or pending is None or pending.index != self._requested:
            return
        index = pending.index
        with contextlib.suppress(Exception):
            self.emit(ev.Traffic(index=index, chunks=self.drain_traffic()))
            self.emit(
                ev.ShotLost(
                    index=index,
                    reason=f"the run stopped during this shot ({type(exc).__name__}: {exc}); "
                    "it may have been fired, so it is not fired again",
                )
            )

    # -- messages ---------------------------------------------------------------------------
    def handle(self, msg: Msg) -> Any:
        """Carry out one message and return its answer."""
        if isinstance(msg, Record):
            if isinstance(msg.event, ev.ShotRequested):
                self._check_request(msg.event)
            if isinstance(msg.event, ev.RunFinished):
                self.flush_traffic()  # nothing the devices said is left out of a closed run
            self.emit(msg.event)
            return None
        if isinstance(msg, Checkpoint):
            return self._hold()
        if isinstance(msg, Ask):
            return self._ask(msg)
        if isinstance(msg, Fire):
            return self._fire(msg)
        if isinstance(msg, Move):
            return self._move(msg.location_in)
        if isinstance(msg, Evaluate):
            return self.backend.evaluate(self.ctx, msg.fired)
        if isinstance(msg, Decide):
            return self.backend.decide(self.ctx)
        if isinstance(msg, Prepare):
            self._stage_at = None
            self.gate_config = self.backend.prepare(self.ctx.q(msg.location_in))
            self._stage_at = msg.location_in
            self.emit(
                ev.LocationSet(
                    from_barrel_end_in=msg.location_in, impact_from_pivot_m=self.ctx.q(msg.location_in)
                )
            )
            return None
        if isinstance(msg, ReadEnvironment):
            return self.backend.environment()
        if isinstance(msg, TimePendulum):
            return self.backend.time_pendulum(msg.cycles)
        if isinstance(msg, ClearFault):
            return self.backend.clear_fault()
        if isinstance(msg, Problem):
            return self.backend.problem(msg.text)
        if isinstance(msg, MeasureCompression | DecideStage):
            backend = self.backend
            if not isinstance(backend, BreakInBackend):
                raise PlanError(f"{type(msg).__name__}: this backend has no compression tester nor stages")
            if isinstance(msg, MeasureCompression):
                return backend.compression()
            return backend.decide_stage(self.ctx, msg.purpose, msg.hoop_hz)
        if isinstance(msg, AskRolling):
            return self._ask_rolling(msg)
        raise TypeError(f"the executor has no handler for {type(msg).__name__}")

    def _check_request(self, event: ev.ShotRequested) -> None:
        """A shot is requested only when none is unresolved, and numbered next."""
        pending = self.state.pending
        if pending is not None:
            raise PlanError(
                f"shot {event.index} requested while shot {pending.index} is unresolved "
                "(a resumed plan resolves it first: rig.plans.resolve_pending)"
            )
        if event.index != len(self.state.shots) + 1:
            raise PlanError(f"shot {event.index} requested; the next shot is {len(self.state.shots) + 1}")

    def _hold(self) -> None:
        """Honour pause and abort."""
        if self.control.paused:
            self.emit(ev.RunPaused())
            self.control.wait()
            if not self.control.aborted:
                self.emit(ev.RunContinued())
        if self.control.aborted:
            raise RunAborted(self.control.reason)

    def _ask(self, msg: Ask) -> bool:
        self.emit(ev.OperatorPrompted(prompt_id=msg.prompt_id, text=msg.text))
        said = self.operator.ask(msg.prompt_id, msg.text)
        how = said if isinstance(said, Answer) else None  # a bare bool does not say how it was given
        answer = bool(said.value if isinstance(said, Answer) else said)
        self.emit(
            ev.OperatorAnswered(
                prompt_id=msg.prompt_id,
                answer=answer,
                who=self.ctx.who,
                given=None if how is None else how.given,
                with_prompt=None if how is None else how.with_prompt,
            )
        )
        return answer

    def _ask_rolling(self, msg: AskRolling) -> Rolling:
        """Ask for a rolling step; the prompt and what the operator reports are recorded."""
        self.emit(ev.OperatorPrompted(prompt_id=msg.prompt_id, text=msg.text))
        if not isinstance(self.operator, RollingOperator):
            raise RunAborted(
                "the operator cannot report a rolling step (depth, passes, who): "
                "run the break-in with an operator that can (docs/standards.md, ABI)"
            )
        said = self.operator.roll(msg.prompt_id, msg.text, msg.depth_in, msg.passes)
        self.emit(
            ev.BarrelRolled(
                stage=msg.stage,
                depth_in=said.depth_in,
                passes=said.passes,
                who=said.who,
                given=said.given,
                hoop_hz=said.hoop_hz,
                hoop_u_hz=said.hoop_u_hz,
            )
        )
        return said

    def _move(self, loc_in: float) -> None:
        """Command the stage to `loc_in` and wait for it there; only then is the position known."""
        if self._stage_at == loc_in:
            return
        self._stage_at = None
        q = self.ctx.q(loc_in)
        self.backend.move(q)
        self._stage_at = loc_in
        self.emit(ev.LocationSet(from_barrel_end_in=loc_in, impact_from_pivot_m=q))

    def _fire(self, msg: Fire) -> Fired | None:
        """Fire and record the raw data, or the loss; None if the shot was lost."""
        index, pending = msg.index, self.state.pending
        if (
            pending is None
            or pending.index != index
            or self._requested != index
            or shot_refuse(ev.SHOT_FIRED, pending.status) is not None
        ):
            raise PlanError(
                f"fire shot {index}: no intent recorded for it in this session "
                "(record ShotRequested with its index and location first; a shot fires once)"
            )
        if pending.location_in != msg.location_in:
            raise PlanError(
                f"fire shot {index} at {msg.location_in:g} in: it was requested at {pending.location_in:g} in"
            )
        if self.gate_config is None:
            raise PlanError("fire before prepare: the gates' configuration is not known")
        if self.control.aborted:  # an abort is honoured even by a plan that caught it
            raise RunAborted(self.control.reason)
        self._move(msg.location_in)  # never fire where this session did not put the stage
        config = self.ctx.config.model_copy(update={"impact_from_pivot_m": self.ctx.q(msg.location_in)})
        try:
            fired = self.backend.fire(
                config, msg.aim_speed_m_s, self.gate_config, self._live(index), msg.ball
            )
        except ShotFailed as exc:  # nothing at all came back: no raw record to keep
            self._record_fired(index, None, msg.ball)
            self.emit(ev.ShotLost(index=index, reason=str(exc)))
            return None
        except DeviceError as exc:
            self._stage_at = None  # a device may have been reset or reopened: command the stage again
            self.emit(ev.Traffic(index=index, chunks=self.drain_traffic()))
            self.emit(ev.ShotLost(index=index, reason=f"{type(exc).__name__}: {exc}"))
            self.backend.recover(exc)
            return None
        self._record_fired(index, fired, msg.ball)
        return fired

    def _record_fired(self, index: int, fired: Fired | None, ball: str | None) -> None:
        raw = fired.record.raw_dict() if fired is not None else {"crossings": []}
        st = self.state
        hits = st.ball_hits if ball is not None else None
        self.emit(ev.ShotFired(index=index, ball_number=st.ball_number, ball=ball, ball_hits=hits, **raw))
        self.emit(ev.Traffic(index=index, chunks=self.drain_traffic()))

    def _live(self, index: int) -> Callable[[GateCrossing], None]:
        """Feed each gate event to a tracker; speeds go out as live events as soon as known."""
        assert self.gate_config is not None
        tracker = ShotTracker(self.gate_config, self.ctx.config.gates.positions_m)

        def on_crossing(c: GateCrossing) -> None:
            self.emit(ev.GateCrossed(index=index, gate=c.gate, tick=c.tick, host_time_s=c.host_time_s))
            for update in tracker.add(c):
                if isinstance(update, InboundKnown):
                    self.emit(ev.InboundMeasured(index=index, speed_m_s=update.v))
                elif isinstance(update, ReboundKnown):
                    self.emit(ev.ReboundMeasured(index=index, speed_m_s=update.v))

        return on_crossing


def context_from(history: list[RunEvent], **kw: Any) -> PlanContext:
    """A plan context whose state is the fold of `history`."""
    return PlanContext(state=fold(history), **kw)
