"""Certify a bat: store, devices, procedure runner and subscribers wired together.

Every persisted event is appended to the store (committed) before the runner goes on, so a run
killed at any moment resumes from its record: no shot lost, none fired twice.
"""

from __future__ import annotations

import base64
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from protocols.procedure import Procedure
from protocols.runner import Operator, RunAborted, RunControl, Runner
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError
from rig.core.events import RunEvent, Subscriber
from rig.modal.link import with_measured_hoop
from rig.session import RigSession
from rig.store import Store


@dataclass(frozen=True)
class Outcome:
    """How a certification run ended."""

    run_id: str
    status: str  # finished | interrupted
    verdict: dict[str, Any] | None
    reason: str = ""


def history(store: Store, run_id: str) -> list[RunEvent]:
    """A run's recorded events, in order (the runner folds them to resume)."""
    return [RunEvent(e.kind, e.payload) for e in store.entries(run_id) if e.kind not in ("RunCreated",)]


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
) -> Outcome:
    """Run (or with `run_id`, resume) a certification; returns its outcome.

    `on_open` sees the open session before the runner starts: an operator console uses it to read
    device status on the runner's thread while the runner waits for the operator.
    """
    listeners = list(subscribers)
    resuming = run_id is not None
    if run_id is None:
        bat = with_measured_hoop(store, bat)  # hoop_hz from the bat's linked modal result, if any
        if bat.id not in store.bats():
            store.register_bat(bat.id, bat.model_dump(mode="json"))
        elif store.bats()[bat.id] != bat.model_dump(mode="json"):
            raise ConfigError(
                f"bat {bat.id} is registered with other properties; give it a new id", source="bat file"
            )
        run_id = store.create_run(procedure.standard.value, bat.id, {"procedure": procedure.name})

    def emit(event: RunEvent) -> None:
        if event.persisted:
            store.append(run_id, event.kind, event.data)
        for listener in listeners:
            listener(event)

    # One runner per run: a second one is refused here (RunLocked), before any device opens.
    with store.run_lock(run_id), RigSession.open(config) as session:
        past = history(store, run_id) if resuming else []  # read under the lock
        if on_open is not None:
            on_open(session)
        session.traffic.clear()  # opening chatter belongs to no shot
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
        )
        try:
            verdict = runner.run()
        except RunAborted as exc:
            if runner.state.finished:  # e.g. a failed ring check ends the run with FAIL
                store.set_run_status(run_id, "finished", runner.state.verdict.get("verdict"))
                return Outcome(run_id, "finished", runner.state.verdict, str(exc))
            emit(RunEvent("RunInterrupted", {"reason": str(exc)}))
            return Outcome(run_id, "interrupted", None, str(exc))
        store.set_run_status(run_id, "finished", verdict["verdict"])  # sealed under the lock
    return Outcome(run_id, "finished", verdict)


def default_db() -> Path:
    """Where records go when no --db is given: rig-records.db in the working directory."""
    return Path("rig-records.db")
