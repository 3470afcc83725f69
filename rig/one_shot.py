"""`rig shot` as a recorded run: one shot fired through the executor, its intent committed before FIRE.

The run is rehearsed, created, identified, locked, recorded, sealed and signed as a certification
is (rig.certification); its plan is rig.protocols.one_shot, its kind in the store `shot`. It obeys
every interlock a certification does (an open one: no FIRE, the loss recorded). It has no verdict:
its plan ends it after the evaluation (RunEnded, sealed as ended); a shot not measured (refused,
lost, a device fault) ends it with the reason, so that no one-shot run is left open to resume.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rig.certification import Driven, Emit, NewRun, Signoff, end_run, live_executor, record_run
from rig.core.config import RigConfig
from rig.core.devices import CannonState
from rig.core.errors import ConfigError, DeviceError, RigError
from rig.core.events import RunEvent, Subscriber
from rig.core.outcomes import ShotOutcome
from rig.core.run_phase import RunPhase
from rig.protocols.control import ScriptedOperator
from rig.protocols.dryrun import Rehearsal, rehearse
from rig.protocols.executor import LiveRig
from rig.protocols.one_shot import ITEM_ID, ITEM_SPEC, KIND, OneShot, OneShotContext, one_shot
from rig.protocols.state import fold
from rig.session import RigSession
from rig.store import Store

__all__ = ["KIND", "OneShot", "RehearsedShot", "ShotNotMeasured", "ShotRun", "fire_one_shot", "rehearse_shot"]

WHO = "rig shot"
FAULT_HINT = "the cannon is left in FAULT (tank vented); the next `rig shot` resets it"


class ShotNotMeasured(RigError):
    """The one shot was refused, lost or fired without its speeds measured; its run is recorded."""


@dataclass(frozen=True)
class ShotRun:
    """A one-shot run that fired: its id, the shot's record (the raw part as ShotFired holds it, and
    the speeds derived from it) and the evaluation (as ShotEvaluated holds it)."""

    run_id: str
    record: dict[str, Any]
    evaluation: ShotOutcome
    signing: str = ""

    @property
    def measured(self) -> bool:
        """Whether the shot's speeds were measured (else `evaluation` says why not)."""
        return self.evaluation.valid


def _in_fault(cannon: Any) -> bool:
    """True if the cannon says it is in FAULT (False if it cannot say)."""
    try:
        return cannon.status().state is CannonState.FAULT
    except DeviceError:
        return False


class OneShotRig(LiveRig):
    """The session's devices for one shot: a fault left by an earlier shot is reset (and said); a
    device error stops the run, and a cannon it left in FAULT stays so until the next shot."""

    def __init__(self, session: RigSession, said: Callable[[str], None]) -> None:
        super().__init__(session.cannon, session.gates, session.clamp)
        self.said = said

    def clear_fault(self) -> None:
        """Reset a cannon an earlier session left in FAULT (a misfire vents the tank), and say so."""
        if _in_fault(self.cannon):
            self.cannon.reset()
            self.said("the cannon was in FAULT (left by an earlier shot); reset it to SAFE")

    def recover(self, exc: DeviceError) -> None:
        """The one shot is over: the error stops the run (recorded), naming a FAULT left behind."""
        if _in_fault(self.cannon):
            raise DeviceError("cannon", f"{str(exc).removeprefix('cannon: ')}; {FAULT_HINT}") from exc
        raise exc


@dataclass(frozen=True)
class RehearsedShot:
    """A shot asked of a rig and rehearsed against checking fakes: it fits the rig."""

    config: RigConfig
    shot: OneShot
    rehearsal: Rehearsal


def rehearse_shot(config: RigConfig, shot: OneShot) -> RehearsedShot:
    """The one rehearsal of a shot, before anything is opened or recorded: an aim outside the
    calibration or a stage position out of range is a ConfigError naming every problem."""
    rehearsal = rehearse(None, None, config, one_shot, None, context=OneShotContext, shot=shot)  # type: ignore[arg-type]
    if rehearsal.problems:
        raise ConfigError("; ".join(rehearsal.problems), source="dry run")
    return RehearsedShot(config, shot, rehearsal)


def fire_one_shot(
    store: Store,
    rehearsed: RehearsedShot,
    *,
    subscribers: tuple[Subscriber, ...] = (),
    said: Callable[[str], None] = lambda text: None,
) -> ShotRun:
    """Fire a rehearsed shot as a recorded one-shot run in `store`.

    A shot that was not fired, or fired and lost, raises ShotNotMeasured naming why, the run
    recorded and ended; a shot fired but not measured returns (ShotRun.measured says so). `said`
    hears what the operator should know that is no event (a FAULT reset).
    """
    config, shot = rehearsed.config, rehearsed.shot
    refusal = ConfigError(f"{ITEM_ID} is registered with other properties in this store", source="store")
    new = NewRun(KIND, ITEM_ID, ITEM_SPEC, refusal, {"procedure": "one shot", "shot": shot.as_dict()})

    def start(session: RigSession, past: list[RunEvent], emit: Emit) -> tuple[Driven, Callable[[], Any]]:
        ctx = OneShotContext(None, None, config, fold(past), who=WHO, shot=shot)  # type: ignore[arg-type]
        operator = ScriptedOperator(who=WHO)
        executor = live_executor(session, ctx, emit, operator, None, rig=OneShotRig(session, said))
        return executor, lambda: executor.run(one_shot)

    # never a real rig's key for a simulation (record_run: sign_simulated False)
    outcome = record_run(store, config, new, list(subscribers), start, what="one-shot run")
    run_id = outcome.run_id
    if outcome.status is not RunPhase.ENDED or outcome.result is None:  # ended by its plan, evaluated
        reason = " ".join(outcome.reason.split()) or "the shot was not completed"
        why = "".join(c if c.isprintable() else "?" for c in reason)[:500]  # as a Signoff takes it
        end_run(store, run_id, Signoff(WHO, why))
        raise ShotNotMeasured(reason)
    done = outcome.result
    return ShotRun(run_id, done["record"], done["evaluation"], outcome.signing)
