"""Certify a bat: store, devices, the plan's executor and subscribers wired together.

A certification is asked for with one request (rig.request.CertifyRequest), rehearsed once
(`prepare`) and then recorded and run (`run_prepared`); the API, the CLI and the console all go
this way. Every persisted event is recorded before the plan goes on and committed at its commit
point (rig.store.RunWriter: a shot's intent before FIRE, its raw record, traffic and outcome in one
transaction), so a run killed at any moment resumes from its record: at most the shot in flight
lost, and recorded lost, none fired twice. Any error during a run (a device fault, a signal, a
bug) ends the session with a RunInterrupted entry naming it.
"""

from __future__ import annotations

import base64
import contextlib
import logging
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RecordRefused, RigError, StoreError
from rig.core.events import RunEvent, Subscriber
from rig.core.lab import lab_file, load_lab
from rig.core.outcomes import RunVerdict
from rig.core.run_phase import RunPhase
from rig.core.version import __version__
from rig.instruments import Identified, identify
from rig.keys import Signer, recorded_rig, recorded_simulated, sign_run, signing_for
from rig.modal.link import with_measured_hoop
from rig.protocols.control import BudgetExceeded, Operator, RunControl
from rig.protocols.dryrun import rehearse
from rig.protocols.evaluate import run_calibration
from rig.protocols.executor import Backend, Executor, LiveRig
from rig.protocols.plan import PlanContext
from rig.protocols.procedure import Procedure
from rig.protocols.runner import run_to_verdict
from rig.protocols.state import RunState
from rig.protocols.steps import plan_name
from rig.quality.records import rig_quality
from rig.report.cert_retest import retest_meta
from rig.request import CertifyRequest, Prepared, Signoff
from rig.session import RigSession
from rig.store import RunLocked, RunWriter, Store, StoreDamaged, StoreGone

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Outcome:
    """How a certification run ended."""

    run_id: str
    status: RunPhase  # finished | interrupted | ended: the run table's words (rig.core.run_phase)
    verdict: RunVerdict | None
    reason: str = ""
    budget_exceeded: bool = False  # resume only with a recorded rig check (Signoff), or end the run
    signing: str = ""  # what the operator should know of the run's signature (rig.keys.Signing)
    result: Any = None  # what a plan that ends without a verdict returned (a one-shot run's shot)


def history(store: Store, run_id: str) -> list[RunEvent]:
    """A run's recorded events, in order (the runner folds them to resume)."""
    return ev.parse_log(store.entries(run_id))


def _traffic_drain(session: RigSession) -> Callable[[], list[dict[str, Any]]]:
    def drain() -> list[dict[str, Any]]:
        taken, session.traffic[:] = list(session.traffic), []
        return [
            {
                "device": dev,
                "t_s": rec.t_s,
                "dir": rec.direction,
                "data_b64": base64.b64encode(rec.data).decode("ascii"),
            }
            for dev, rec in taken
        ]

    return drain


def _running(store: Store, run_id: str, source: str) -> None:
    """Refuse to go on with a run that is already closed."""
    summary = store.run(run_id)
    if summary.status == "finished":
        raise ConfigError(f"run {run_id} is already finished ({summary.verdict})", source=source)
    if summary.status != "running":
        raise ConfigError(f"run {run_id} was ended without a verdict; start a new one", source=source)


def _seal(store: Store, run_id: str, status: str, verdict: str | None, signer: Signer | None) -> None:
    """Seal the run; with the rig's key, sign the anchor of its last entry (RunSigned); then read it
    back from the store as another reader would (Store.confirm_sealed): only then is it reported."""
    seal = store.set_run_status(run_id, status, verdict)
    if signer is not None:
        sign_run(store, run_id, signer)
    try:
        store.confirm_sealed(run_id, seal)
    except StoreError as exc:  # sealed, so not resumable: nothing the store does not hold is reported
        message = f"{exc}; run {run_id} was sealed but does not read back whole: no verdict is given"
        raise RunNotRecorded(run_id, message, resumable=False) from exc


def _checked(store: Store, run_id: str | None = None) -> None:
    """Store.check_integrity, its refusal saying that nothing was recorded."""
    try:
        store.check_integrity(run_id)
    except StoreDamaged as exc:
        raise StoreDamaged(f"{exc}; nothing recorded") from None


class RunNotRecorded(StoreError):
    """The store failed a run after it was created (full, gone, unwritable): the run stopped with no
    verdict, and its interruption may not be recorded; `resumable` once the store takes writes again."""

    def __init__(self, run_id: str, message: str, *, resumable: bool) -> None:
        super().__init__(message)
        self.run_id, self.resumable = run_id, resumable


def end_run(store: Store, run_id: str, signoff: Signoff) -> Outcome:
    """End an unfinished run with no verdict, on the operator's recorded word (store status aborted)."""
    _running(store, run_id, "--end")
    rig = recorded_rig(store, run_id)
    # a key file open to others stops us here
    signing = signing_for(store, rig, simulated=recorded_simulated(store, run_id)) if rig else None
    signer = signing.signer if signing else None
    with store.run_lock(run_id):  # never while a runner is still working on the run
        shots = len(store.entries(run_id, kinds=[ev.SHOT_REQUESTED]))
        said = signoff.as_dict()  # who and why, stripped
        ended = ev.RunEnded(who=said["who"], why=said["why"], shots_so_far=shots)
        store.append(run_id, ended.kind, ended.data)
        _seal(store, run_id, "aborted", None, signer)
    reason = f"ended without a verdict by {signoff.who}: {signoff.why}"
    return Outcome(run_id, RunPhase.ENDED, None, reason, signing=signing.note if signing else "")


def _reason(exc: BaseException) -> str:
    if isinstance(exc, RigError | KeyboardInterrupt) and str(exc):
        return str(exc)
    return f"unexpected {type(exc).__name__}: {exc}"


def _where(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    return "; ".join(f"{Path(f.filename).name}:{f.lineno} in {f.name}" for f in frames[-3:])


def prepare(store: Store, request: CertifyRequest, *, gated: bool = True) -> Prepared:
    """The one rehearsal of a certification, before anything is recorded or opened: a new run's bat
    takes its measured hoop (rig.modal.link, before the rig is built: a simulated bat takes it as its
    own), the rig config is built, the plan (a resumed run: what is left of it) is rehearsed against
    checking fakes, and a new run's named calibration is loaded. Every problem: one ConfigError.
    `gated`: a new run on a rig whose control charts signal, unacknowledged, is refused (rig check)."""
    run_id, bat = request.run_id, request.bat
    if run_id is not None:
        _running(store, run_id, "--resume")
    else:
        needs_ball_cor(request)
        bat = with_measured_hoop(store, bat)  # hoop_hz from the bat's linked modal result, if any
    config = request.config_for(bat)
    if gated and run_id is None:
        refusal = rig_quality(store, config.identity_name()).refusal()
        if refusal:
            raise ConfigError(refusal, source="quality control")
    past = history(store, run_id) if run_id is not None else None
    rehearsal = rehearse(request.procedure, bat, config, request.plan, past, options=request.options)
    if rehearsal.problems:
        raise ConfigError("; ".join(rehearsal.problems), source="dry run")
    lab = None
    if run_id is None:
        run_calibration(request.procedure, config)  # a named calibration that will not load stops us here
        named = lab_file(request.lab, config.identity.lab)
        lab = None if named is None else load_lab(named)  # a bad lab file stops us here
    return Prepared(request, bat, config, rehearsal, lab)


def needs_ball_cor(request: CertifyRequest) -> None:
    """A BPF divides by the lot's ball COR: a new BPF run without a lot's ball-cor result is refused."""
    p = request.procedure
    if p.metric.needs_ball_cor and (request.ball or {}).get("wall_cor") is None:
        raise ConfigError(
            f"{p.standard} is BBCOR / ball COR: name the lot the balls come from, with a ball-cor "
            "result (rig balls test --procedure ball-cor --lot LOT, then --ball-lot LOT)",
            source="--ball-lot",
        )


def run_prepared(store: Store, prepared: Prepared, *, kind: str | None = None) -> Outcome:
    """Record and run a rehearsed certification (with its `run_id`: resume it); returns its outcome.

    The listeners first hear RigNamed: the rig, whether it is simulated, and what its signature will
    be (`sign_simulated`: sign a simulated run even with a real rig's key, rig.keys.signing_for).
    `rig_checked` records that the rig was checked (who, why): the re-shoot budget starts again.
    `accept_overdue` (who, why) lets instruments past their calibration due date be used, recorded
    with the instruments' identities (rig.instruments); without it such a run is refused. `on_open`
    sees the open session before the plan starts: an operator console reads device status through it
    on the run's thread while the run waits for the operator. `kind`: the run's kind in the store
    (default the procedure's metric; `check` for a check run). A new run made while the rig's
    control-chart signals stand acknowledged records the acknowledgement (RunCreated's check_ack).
    """
    request, bat, config = prepared.request, prepared.bat, prepared.config
    refusal = ConfigError(
        f"bat {bat.id} is registered with other properties; give it a new id", source="bat file"
    )
    p = request.procedure
    meta: dict[str, Any] = {"procedure": p.name, "report": prepared.report_meta()}
    if plan_name(request.plan) is not None:  # a run that never starts is resumed with its plan too
        meta["plan"] = plan_name(request.plan)
    under = rig_quality(store, config.identity_name()).under if request.run_id is None else None
    if under is not None:
        meta["check_ack"] = under.as_dict()
    if request.run_id is None and kind is None:  # a certification of a retained bat: its last result
        meta.update(retest_meta(store, p.standard, bat.id))
    new = NewRun(kind or p.standard, bat.id, bat.registered(), refusal, meta)

    def start(session: RigSession, past: list[RunEvent], emit: Emit) -> tuple[Driven, Callable[[], Any]]:
        executor = live_executor(session, prepared.context(past), emit, prepared.operator, request.control)
        return executor, lambda: run_to_verdict(executor, request.plan)

    return record_run(
        store,
        config,
        request.run_id or new,
        list(request.subscribers),
        start,
        on_open=request.on_open,
        override=None if request.accept_overdue is None else request.accept_overdue.as_dict(),
        sign_simulated=request.sign_simulated,
    )


@dataclass(frozen=True)
class NewRun:
    """A run to create: its kind, what the clamp holds (registered once; `refusal` if the store holds
    that id with other properties) and what RunCreated records besides the rig's identity."""

    kind: str
    item_id: str
    item_spec: dict[str, Any]
    refusal: ConfigError
    meta: dict[str, Any] = field(default_factory=dict)


def record_run(
    store: Store,
    config: RigConfig,
    run: str | NewRun,
    listeners: list[Subscriber],
    start: Start,
    *,
    what: str = "run",
    on_open: Callable[[RigSession], None] | None = None,
    override: dict[str, str] | None = None,
    sign_simulated: bool = False,
) -> Outcome:
    """Record and drive one run on the rig of `config`: `run` a run id to resume, or a NewRun,
    created only once its devices are open and its instruments identified (overdue, a wrong serial:
    refused, nothing recorded). The listeners first hear RigNamed: the rig, whether it is simulated,
    and what its signature will be (`sign_simulated`: even with a real rig's key, rig.keys.signing_for);
    the outcome carries that note. `start`, `on_open`, `override`: as drive takes them."""
    identity = config.identity_record(__version__)
    rig = (recorded_rig(store, run) if isinstance(run, str) else None) or str(identity["name"])
    signing = signing_for(store, rig, simulated=config.simulated, sign_simulated=sign_simulated)
    session: RigSession | None = None  # a resumed run opens its devices under its lock (drive)
    identified: ev.InstrumentsIdentified | None = None  # ... and is identified there, once they are open
    if isinstance(run, NewRun):
        _checked(store)  # nothing is recorded into a damaged store (a resumed run: in drive)
        register_item(store, run.item_id, run.item_spec, run.refusal)
        session = open_before_run(config)  # a port that will not open: refused, no run created
        identified = instruments_or_close(session, config, override)  # overdue, wrong serial: refused
        run_id = create_run(store, session, run.kind, run.item_id, {**run.meta, "rig": identity})
    else:
        run_id = run
    named = ev.RigNamed(name=rig, simulated=config.simulated, signing=signing.note)
    outcome = drive(
        store,
        run_id,
        config,
        listeners,
        signing.signer,
        start,
        resuming=isinstance(run, str),
        on_open=on_open,
        what=what,
        session=session,
        named=named,
        identified=identified,
        override=override,
    )
    return replace(outcome, signing=signing.note)


def certify(store: Store, procedure: Procedure, bat: BatSpec, config: RigConfig, **options: Any) -> Outcome:
    """Run (or with `run_id=`, resume) a certification: CertifyRequest(procedure, bat, config,
    **options) prepared (rehearsed once) and run. The entry points build the request themselves."""
    return run_prepared(store, prepare(store, CertifyRequest(procedure, bat, config, **options)))


def live_executor(
    session: RigSession,
    ctx: PlanContext,
    emit: Emit,
    operator: Operator | None,
    control: RunControl | None,
    rig: Backend | None = None,
) -> Executor:
    """The executor of a plan on a session's devices (`rig`: a backend of its own over them)."""
    backend = rig or LiveRig(session.cannon, session.gates, session.clamp, session.compression)
    return Executor(ctx, backend, emit, operator, control, _traffic_drain(session))


Emit = Callable[[RunEvent], None]
Start = Callable[[RigSession, list[RunEvent], Emit], tuple["Driven", Callable[[], Any]]]


class Driven(Protocol):
    """What drive needs of a run's runner or executor: its state, its control, its unsent traffic."""

    @property
    def state(self) -> RunState: ...

    @property
    def control(self) -> RunControl: ...

    def flush_traffic(self) -> None: ...


def open_before_run(config: RigConfig) -> RigSession:
    """A new run's devices, opened before the run is created: a port that cannot be opened is a
    ConfigError naming it, with nothing recorded (not a run created only to be interrupted)."""
    try:
        return RigSession.open(config)
    except (RigError, OSError) as exc:
        raise ConfigError(f"the devices could not be opened ({_reason(exc)}); no run was started") from None


def instruments_or_close(
    session: RigSession, config: RigConfig, override: dict[str, str] | None
) -> ev.InstrumentsIdentified:
    """A new run's instruments, identified before the run is created: an overdue calibration
    without an override, or a serial number that is not the listed one, is a ConfigError (one
    line, the devices closed, nothing recorded)."""
    try:
        identified = identify(session, config, override)
    except BaseException:
        session.close()
        raise
    if identified.refusals:
        session.close()
        raise ConfigError("; ".join(identified.refusals) + "; no run was started", source="instruments")
    return identified.event


def create_run(store: Store, session: RigSession, kind: str, item_id: str, meta: dict[str, Any]) -> str:
    """store.create_run, closing the session opened for the run if the store refuses."""
    try:
        return store.create_run(kind, item_id, meta)
    except BaseException:
        session.close()
        raise


def drive(
    store: Store,
    run_id: str,
    config: RigConfig,
    listeners: list[Subscriber],
    signer: Signer | None,
    start: Start,
    *,
    resuming: bool,
    on_open: Callable[[RigSession], None] | None = None,
    what: str = "run",
    session: RigSession | None = None,
    named: RunEvent | None = None,
    identified: RunEvent | None = None,
    override: dict[str, str] | None = None,
) -> Outcome:
    """Run one recorded run on the rig under its lock: every persisted event recorded before the
    plan goes on (committed at its commit point), any error recorded as the run's interruption
    (resumable), the run sealed (and
    signed) at its end. `start` builds the runner from the open session, the record and `emit`, and
    returns it with the call that runs it to its verdict. `session`: a new run's devices, opened
    before the run was created (open_before_run); None: opened here, under the lock.

    The store is checked before the run goes on (Store.check_integrity); the verdict reaches the
    listeners only once the run is sealed and read back; a store that fails the run (full, gone)
    raises RunNotRecorded naming the run. `named` (RigNamed) goes to the listeners first, once the
    lock is held and the store checked: a refused runner says nothing else. `identified`: a new
    run's instruments (instruments_or_close); None: identified here once the devices open, and an
    instrument the run may not use (`override` aside) interrupts it, resumable."""
    verdicts: list[RunEvent] = []  # RunFinished: shown once sealed and read back, never before
    writer = RunWriter(store, run_id)  # entries that may wait go with the next commit point

    def emit(event: RunEvent) -> None:
        if event.persisted:
            writer.record(event.kind, event.data, commit=event.commits)
        if event.kind == ev.RUN_FINISHED:
            verdicts.append(event)
            return
        for listener in listeners:
            listener(event)

    opened = session  # a new run's devices: closed below however the lock goes (close is idempotent)
    try:
        outcome = _drive(
            writer,
            config,
            emit,
            signer,
            start,
            resuming,
            on_open,
            what,
            session,
            named,
            identified,
            override,
        )
    except (RunLocked, RunNotRecorded, StoreDamaged):  # refused before anything was recorded, or said
        raise
    except StoreError as exc:  # the store failed the run after it was created: say which run
        gone = isinstance(exc, StoreGone)
        raise RunNotRecorded(
            run_id, f"{exc}; run {run_id} stopped without a verdict", resumable=not gone
        ) from exc
    finally:
        if opened is not None:
            opened.close()
    for event in verdicts if outcome.status is RunPhase.FINISHED else []:
        for listener in listeners:
            listener(event)
    return outcome


def _drive(
    writer: RunWriter,
    config: RigConfig,
    emit: Emit,
    signer: Signer | None,
    start: Start,
    resuming: bool,
    on_open: Callable[[RigSession], None] | None,
    what: str,
    session: RigSession | None,
    named: RunEvent | None = None,
    identified: RunEvent | None = None,
    override: dict[str, str] | None = None,
) -> Outcome:
    # One runner per run: a second one is refused here (RunLocked), before it opens a device (a new
    # run's are open already: no other runner can know the run yet).
    store, run_id = writer.store, writer.run_id
    with store.run_lock(run_id):
        _checked(store, run_id)  # never record into a store that verify would call damaged
        if named is not None:
            emit(named)  # which rig, how it is signed: said once the lock is held and the store checked
        if session is None:
            try:
                session = RigSession.open(config)
            except (RigError, OSError) as exc:  # an unplugged or busy port: nothing moved, resumable
                reason = f"the devices could not be opened: {_reason(exc)}"
                emit(ev.RunInterrupted(reason=reason, budget_exceeded=False))
                return Outcome(run_id, RunPhase.INTERRUPTED, None, reason)
        with session:
            if identified is None:
                try:
                    found = identify(session, config, override)
                except RigError as exc:
                    found = Identified(ev.InstrumentsIdentified(devices={}, equipment=[]), (_reason(exc),))
                if found.refusals:
                    reason = "; ".join(found.refusals)
                    emit(ev.RunInterrupted(reason=reason, budget_exceeded=False))
                    return Outcome(run_id, RunPhase.INTERRUPTED, None, reason)
                identified = found.event
            past = history(store, run_id) if resuming else []  # read under the lock
            if on_open is not None:
                on_open(session)
            session.traffic.clear()  # opening chatter belongs to no shot
            driven, run = start(session, past, _then_after_start(emit, identified))
            # one control may steer several runs (rig-study population --certify)
            driven.control.settled = False
            try:
                verdict = run()
                driven.control.settled = True
                writer.commit()  # nothing held is left out of the sealed run
            except BaseException as exc:
                driven.control.settled = True  # stop signals from now on would only tear the record up
                if not isinstance(exc, Exception | KeyboardInterrupt):
                    with contextlib.suppress(Exception):
                        writer.commit()  # a stop that is not a crash keeps what was held
                    raise  # SystemExit and the like: not an interruption of the run
                ended = driven.state.verdict
                if driven.state.phase is RunPhase.FINISHED and ended is not None:  # a failed ring check
                    writer.commit()
                    _seal(store, run_id, "finished", ended.verdict, signer)
                    return Outcome(run_id, RunPhase.FINISHED, ended, str(exc))
                reason, budget = _reason(exc), isinstance(exc, BudgetExceeded)
                where = None
                if not isinstance(exc, RigError | KeyboardInterrupt):  # a bug: say where, for the developers
                    where = _where(exc)
                    log.debug("%s %s interrupted by an unexpected error", what, run_id, exc_info=exc)
                try:
                    with contextlib.suppress(Exception):
                        driven.flush_traffic()
                    emit(ev.RunInterrupted(reason=reason, budget_exceeded=budget, where=where))
                except KeyboardInterrupt:  # forced while recording: the record stays whole, resumable
                    pass
                except StoreError as failed:  # the store that failed the run refuses its interruption too
                    message = (
                        f"{failed}; run {run_id} stopped without a verdict (its interruption is not recorded)"
                    )
                    raise RunNotRecorded(
                        run_id, message, resumable=not isinstance(failed, StoreGone)
                    ) from exc
                return Outcome(run_id, RunPhase.INTERRUPTED, None, reason, budget)
            if driven.state.phase is RunPhase.ENDED:  # a plan that ends without a verdict (rig.one_shot)
                _seal(store, run_id, "aborted", None, signer)  # under the lock
                return Outcome(run_id, RunPhase.ENDED, None, result=verdict)
            if not isinstance(verdict, RunVerdict):
                raise TypeError(f"the plan finished run {run_id} and returned no verdict: {verdict!r}")
            _seal(store, run_id, "finished", verdict.verdict, signer)  # sealed under the lock
    return Outcome(run_id, RunPhase.FINISHED, verdict)


def _then_after_start(emit: Emit, identified: RunEvent) -> Emit:
    """`emit` that records `identified` (what each device said it is) right after the session's
    RunStarted or RunResumed, before anything moves."""
    pending = [identified]

    def then(event: RunEvent) -> None:
        emit(event)
        if pending and event.kind in (ev.RUN_STARTED, ev.RUN_RESUMED):
            emit(pending.pop())

    return then


def register_item(store: Store, item_id: str, spec: dict[str, Any], refusal: ConfigError) -> None:
    """Register what the clamp holds (a bat, a ball test's target) once; `refusal` if the store
    already holds that id with other properties (another rig may register it meanwhile)."""
    registered = store.bats().get(item_id)
    if registered is None:
        with contextlib.suppress(RecordRefused):  # another rig registered it meanwhile (one lab database)
            store.register_bat(item_id, spec)
        registered = store.bats().get(item_id)
    if registered != spec:
        raise refusal


def default_db() -> Path | str:
    """Where records go when no --db is given: $RIG_DB, else rig-records.db in the working directory."""
    from rig.core.dbpath import default_db as where

    return where()
