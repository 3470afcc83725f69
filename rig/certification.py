"""Certify a bat: store, devices, procedure runner and subscribers wired together.

Every persisted event is appended to the store (committed) before the runner goes on, so a run
killed at any moment resumes from its record: no shot lost, none fired twice. Any error during a
run (a device fault, a signal, a bug) ends the session with a RunInterrupted entry naming it.
"""

from __future__ import annotations

import base64
import contextlib
import logging
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RecordRefused, RigError, StoreError
from rig.core.events import RunEvent, Subscriber
from rig.core.run_phase import RunPhase
from rig.core.version import __version__
from rig.instruments import Identified, identify
from rig.keys import Signer, recorded_rig, recorded_simulated, sign_run, signing_for
from rig.modal.link import with_measured_hoop
from rig.protocols.dryrun import rehearse
from rig.protocols.evaluate import run_calibration
from rig.protocols.plan import PlanFactory
from rig.protocols.procedure import Procedure
from rig.protocols.runner import BudgetExceeded, Operator, RunControl, Runner
from rig.protocols.state import RunState
from rig.protocols.steps import certification
from rig.session import RigSession
from rig.store import RunLocked, Store, StoreDamaged, StoreGone

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Outcome:
    """How a certification run ended."""

    run_id: str
    status: RunPhase  # finished | interrupted | ended: the run table's words (rig.core.run_phase)
    verdict: dict[str, Any] | None
    reason: str = ""
    budget_exceeded: bool = False  # resume only with a recorded rig check (Signoff), or end the run
    signing: str = ""  # what the operator should know of the run's signature (rig.keys.Signing)


@dataclass(frozen=True)
class Signoff:
    """Who takes a recorded decision about a run, and why (a rig check, ending a run)."""

    who: str
    why: str

    def __post_init__(self) -> None:
        for name, text in (("who", self.who), ("why", self.why)):
            if not isinstance(text, str) or not text.strip() or len(text) > 500 or not text.isprintable():
                raise ConfigError(
                    f"give a name and a reason ({name}: 1-500 printable characters)", source=name
                )

    def as_dict(self) -> dict[str, str]:
        """JSON-ready view."""
        return {"who": self.who.strip(), "why": self.why.strip()}


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


def certify(
    store: Store,
    procedure: Procedure,
    bat: BatSpec,
    config: RigConfig,
    *,
    run_id: str | None = None,
    operator: Operator | None = None,
    subscribers: Iterable[Subscriber] = (),
    control: RunControl | None = None,
    confirm_fire: bool = False,
    review_shots: bool = False,
    on_open: Callable[[RigSession], None] | None = None,
    rig_checked: Signoff | None = None,
    plan: PlanFactory = certification,
    ball: dict[str, Any] | None = None,
    sign_simulated: bool = False,
    accept_overdue: Signoff | None = None,
) -> Outcome:
    """Run (or with `run_id`, resume) a certification; returns its outcome.

    `on_open` sees the open session before the runner starts: an operator console uses it to read
    device status on the runner's thread while the runner waits for the operator. `rig_checked`
    records that the rig was checked (who, why): the re-shoot budget starts again. `plan` is the
    procedure's plan (rig.protocols.steps.certification, or a lab's own from the same steps). `ball`:
    the ball terms (rig.protocols.ball_terms.BallTerms fields: the lot, its measured wear, spread and
    sensitivities, the ball law), recorded in RunStarted; None: assumed defaults, budgeted whole.
    `sign_simulated`: sign a simulated run even with a real rig's key (rig.keys.signing_for); the
    listeners first hear RigNamed: the rig, whether it is simulated, and what its signature will be.
    `accept_overdue` (who, why) lets instruments past their calibration due date be used, recorded
    with the instruments' identities (rig.instruments); without it such a run is refused.
    """
    listeners = list(subscribers)
    override = None if accept_overdue is None else accept_overdue.as_dict()
    resuming = run_id is not None
    if run_id is not None:
        _running(store, run_id, "--resume")
    # rehearse the plan (a resumed run: what is left of it) before anything is recorded or opened
    past = history(store, run_id) if run_id is not None else None
    options = {"ball": ball} if ball is not None else {}
    problems = rehearse(procedure, bat, config, plan, past, options=options).problems
    if problems:
        raise ConfigError("; ".join(problems), source="dry run")
    identity = config.identity_record(__version__)
    rig = (recorded_rig(store, run_id) if run_id else None) or str(identity["name"])
    signing = signing_for(store, rig, simulated=config.simulated, sign_simulated=sign_simulated)
    if run_id is None:
        run_calibration(procedure, config)  # a named calibration that will not load stops us here
        _checked(store)  # nothing is recorded into a damaged store (a resumed run: in drive)
        bat = with_measured_hoop(store, bat)  # hoop_hz from the bat's linked modal result, if any
        refusal = ConfigError(
            f"bat {bat.id} is registered with other properties; give it a new id", source="bat file"
        )
        register_item(store, bat.id, bat.model_dump(mode="json"), refusal)
        meta = {"procedure": procedure.name, "rig": identity}
        session = open_before_run(config)  # a port that will not open: refused, no run created
        identified = instruments_or_close(session, config, override)  # overdue, wrong serial: refused
        run_id = create_run(store, session, procedure.standard, bat.id, meta)
    else:
        session = None  # a resumed run opens its devices under its lock (an error: its interruption)
        identified = None  # identified under the lock, once its devices are open

    def start(session: RigSession, past: list[RunEvent], emit: Emit) -> tuple[Driven, Callable[[], Any]]:
        runner = Runner(
            procedure,
            bat,
            config,
            session.cannon,
            session.gates,
            session.clamp,
            emit,
            operator=operator,
            history=past,
            drain_traffic=_traffic_drain(session),
            control=control,
            confirm_fire=confirm_fire,
            review_shots=review_shots,
            rig_check=None if rig_checked is None else rig_checked.as_dict(),
            plan=plan,
            options=options,
        )
        return runner, lambda: runner.run(rehearse_first=False)  # rehearsed above, before the lock

    named = ev.RigNamed(name=rig, simulated=config.simulated, signing=signing.note)
    outcome = drive(
        store,
        run_id,
        config,
        listeners,
        signing.signer,
        start,
        resuming=resuming,
        on_open=on_open,
        session=session,
        named=named,
        identified=identified,
        override=override,
    )
    return replace(outcome, signing=signing.note)


Emit = Callable[[RunEvent], None]


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
    start: Callable[[RigSession, list[RunEvent], Emit], tuple[Driven, Callable[[], Any]]],
    *,
    resuming: bool,
    on_open: Callable[[RigSession], None] | None = None,
    what: str = "run",
    session: RigSession | None = None,
    named: RunEvent | None = None,
    identified: RunEvent | None = None,
    override: dict[str, str] | None = None,
) -> Outcome:
    """Run one recorded run on the rig under its lock: every persisted event committed before the
    plan goes on, any error recorded as the run's interruption (resumable), the run sealed (and
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

    def emit(event: RunEvent) -> None:
        if event.persisted:
            store.append(run_id, event.kind, event.data)
        if event.kind == ev.RUN_FINISHED:
            verdicts.append(event)
            return
        for listener in listeners:
            listener(event)

    opened = session  # a new run's devices: closed below however the lock goes (close is idempotent)
    try:
        outcome = _drive(
            store,
            run_id,
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
    store: Store,
    run_id: str,
    config: RigConfig,
    emit: Emit,
    signer: Signer | None,
    start: Callable[[RigSession, list[RunEvent], Emit], tuple[Driven, Callable[[], Any]]],
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
    with store.run_lock(run_id):
        _checked(store, run_id)  # never record into a store that verify would call damaged
        if named is not None:
            emit(named)  # which rig, how it is signed: said once the lock is held and the store checked
        if session is None:
            try:
                session = RigSession.open(config)
            except (RigError, OSError) as exc:  # an unplugged or busy port: nothing moved, resumable
                reason = f"the devices could not be opened: {_reason(exc)}"
                emit(ev.RunInterrupted(reason=reason, extra={"budget_exceeded": False}))
                return Outcome(run_id, RunPhase.INTERRUPTED, None, reason)
        with session:
            if identified is None:
                try:
                    found = identify(session, config, override)
                except RigError as exc:
                    found = Identified(ev.InstrumentsIdentified(devices={}, equipment=[]), (_reason(exc),))
                if found.refusals:
                    reason = "; ".join(found.refusals)
                    emit(ev.RunInterrupted(reason=reason, extra={"budget_exceeded": False}))
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
            except BaseException as exc:
                driven.control.settled = True  # stop signals from now on would only tear the record up
                if not isinstance(exc, Exception | KeyboardInterrupt):
                    raise  # SystemExit and the like: not an interruption of the run
                ended = driven.state.verdict
                if driven.state.phase is RunPhase.FINISHED and ended is not None:  # a failed ring check
                    _seal(store, run_id, "finished", ended.get("verdict"), signer)
                    return Outcome(run_id, RunPhase.FINISHED, ended, str(exc))
                reason, budget = _reason(exc), isinstance(exc, BudgetExceeded)
                detail: dict[str, Any] = {"reason": reason, "budget_exceeded": budget}
                if not isinstance(exc, RigError | KeyboardInterrupt):  # a bug: say where, for the developers
                    detail["where"] = _where(exc)
                    log.debug("%s %s interrupted by an unexpected error", what, run_id, exc_info=exc)
                try:
                    with contextlib.suppress(Exception):
                        driven.flush_traffic()
                    emit(ev.event(ev.RUN_INTERRUPTED, **detail))
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
            _seal(store, run_id, "finished", str(verdict["verdict"]), signer)  # sealed under the lock
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
