"""What a resumed certification runs with: the procedure and bat its RunStarted recorded, or, for a
run created but stopped before RunStarted could be recorded (a full disk, a port that would not
open), the ones its RunCreated names, checked, so that it starts from the beginning.

RunCreated records the procedure's standard and name and the bat's id; the bat's properties are
its registration. A built-in procedure is found by its standard; a lab's own procedure file must be
given again (`--procedure FILE`), and must be the one the run was created with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.core.events import ONE_SHOT_KIND as ONE_SHOT
from rig.protocols.procedure import Procedure
from rig.store import RUN_CREATED, Store


@dataclass(frozen=True)
class Recorded:
    """A run's procedure and bat as recorded; `started`: RunStarted is recorded (else it starts anew);
    `plan`: the plan it records (module.function), None for the standard steps."""

    procedure: Procedure
    bat: BatSpec
    started: bool
    plan: str | None = None


def recorded_inputs(store: Store, run_id: str, procedure: Procedure | None = None) -> Recorded:
    """The procedure and bat to resume `run_id` with. `procedure`: given again for a run that never
    started (a lab's own file); for a started run the recorded one is used, whatever is given."""
    if store.run(run_id).procedure == ONE_SHOT:
        raise ConfigError(
            f"run {run_id} is a one-shot run (rig shot): a shot is fired once, never resumed", "--resume"
        )
    started = store.entries(run_id, kinds=[ev.RUN_STARTED])
    if started:
        payload = started[0].payload
        return Recorded(
            Procedure.model_validate(payload["procedure"]),
            BatSpec.model_validate(payload["bat"]),
            True,
            payload.get("plan"),
        )
    created = store.entries(run_id, kinds=[RUN_CREATED])
    payload = created[0].payload if created else {}
    meta: dict[str, Any] = payload["meta"] if isinstance(payload.get("meta"), dict) else {}
    standard, name = payload.get("procedure"), meta.get("procedure")
    if "test" in meta or not isinstance(standard, str) or not isinstance(name, str):
        raise ConfigError(f"run {run_id} never started and records no procedure to start it with", "--resume")
    chosen = procedure if procedure is not None else _builtin(standard)
    if chosen is None or chosen.standard != standard or chosen.name != name:
        raise ConfigError(
            f"run {run_id} never started; it was created with the procedure {name!r} ({standard}): "
            "give that procedure again with --procedure to start it",
            "--resume",
        )
    spec = store.bats().get(str(payload.get("bat_id")))
    if spec is None:
        raise ConfigError(f"run {run_id} never started and its bat is not registered", "--resume")
    plan = meta.get("plan")
    return Recorded(chosen, BatSpec.model_validate(spec), False, plan if isinstance(plan, str) else None)


def recorded_plan_name(store: Store, run_id: str) -> str | None:
    """The plan `run_id` records (RunStarted's, else RunCreated's meta; None: the standard steps)."""
    started = store.entries(run_id, kinds=[ev.RUN_STARTED])
    if started:
        plan = started[0].payload.get("plan")
    else:
        created = store.entries(run_id, kinds=[RUN_CREATED])
        meta = created[0].payload.get("meta") if created else None
        plan = meta.get("plan") if isinstance(meta, dict) else None
    return plan if isinstance(plan, str) else None


def _builtin(standard: str) -> Procedure | None:
    try:
        return Procedure.load(standard)
    except ConfigError:
        return None
