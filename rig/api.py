"""The public Python API: open a store, load a bat, pick a rig, certify (docs/api.md).

A small facade over the controller's own modules, so that a lab scripts a certification with the
names `import rig` gives. Nothing inside the package imports this module: it is the top.
Bad input raises a `RigError` whose message names the cause; a run that stops part way returns a
`Result` with status "interrupted" (its record kept whole, resumable with `resume=run_id`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RigError
from rig.core.events import Verdict  # the one verdict enum (a str, so == "PASS" holds)
from rig.core.outcomes import RunVerdict
from rig.core.run_phase import RunPhase  # the run table's phases (a str, so == "finished" holds)
from rig.protocols.control import Operator, RunControl, ScriptedOperator
from rig.protocols.plan import PlanFactory
from rig.protocols.procedure import Procedure
from rig.store import Store

Bat = BatSpec  # `rig.Bat.load("bat.toml")`: table [bat] of a TOML file
SQLITE_URL = "sqlite://"


def open_store(path: str | Path) -> Store:
    """Open (creating if need be) a record store: a file path, a `sqlite:///path` URL or a lab's
    PostgreSQL database, `postgresql://user@host/dbname` (docs/records.md).

    Use it as a context manager; a file that is not a store raises StoreFileError (a RigError).
    """
    text = str(path)
    if text.startswith(("postgresql://", "postgres://")):
        return Store.open(text, create=True)
    if "://" in text:
        if not text.startswith(SQLITE_URL + "/"):
            scheme = text.split("://", 1)[0]
            raise ConfigError(
                f"{scheme}:// stores are not supported; give a path, sqlite:///PATH or postgresql://...",
                "store",
            )
        text = text[len(SQLITE_URL) + 1 :]  # sqlite:///rel.db -> rel.db, sqlite:////abs.db -> /abs.db
        if not text:
            raise ConfigError("the sqlite URL names no file", "store")
    return Store.open(Path(text).expanduser(), create=True)


@dataclass(frozen=True)
class RigSpec:
    """Which rig to run on: a simulated scene (`simulated`) or a rig file (`from_config`)."""

    source: str
    scene: str | None = None
    config: RigConfig | None = None
    overrides: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    def config_for(self, bat: BatSpec, procedure: Procedure | None = None) -> RigConfig:
        """The rig config; a simulated bat takes `bat`'s properties as its true ones, and a simulated
        lab loads the balls `procedure` names (its ball class) and aims as low as its speed."""
        if self.config is not None:
            return self.config
        from rig.session import sim_config

        assert self.scene is not None
        balls = None if procedure is None else procedure.ball.ball_class
        speed = None if procedure is None else procedure.target_speed_m_s
        named = None if procedure is None else procedure.name
        config = sim_config(self.scene, bat=bat, ball_class=balls, speed_m_s=speed, balls_of=named)
        return _override(config, self.overrides, self.source)


def _override(config: RigConfig, overrides: Mapping[str, Any], source: str) -> RigConfig:
    if not overrides:
        return config
    return RigConfig.from_dict({**config.model_dump(mode="json"), **overrides}, source=source)


def simulated(scene: str = "ideal", **overrides: Any) -> RigSpec:
    """A simulated rig of `scene` (ideal, lab, drag, faulty or a scene TOML file).

    `overrides` replace top-level rig-config fields (e.g. `cannon_cycle_s=30.0`, `timeouts={...}`);
    an unknown scene or a refused field raises ConfigError naming it.
    """
    from rig.session import sim_config

    source = f"simulated({scene!r})"
    _override(sim_config(scene), overrides, source)  # refuse a bad scene or field now, not at certify
    return RigSpec(source=source, scene=scene, overrides=MappingProxyType(dict(overrides)))


def from_config(path: str | Path) -> RigSpec:
    """A rig described by its TOML file (ports, geometry, aim table...); errors name the field."""
    return RigSpec(source=str(path), config=RigConfig.load(path))


@dataclass(frozen=True)
class Result:
    """How a `certify` call ended; the record of truth stays the store's log.

    status: "finished" (a verdict) or "interrupted" (no verdict yet, resumable; `reason` says why),
    a RunPhase (rig.core.run_phase). shots: shots the run has asked the cannon to fire, over all its
    sessions.
    """

    run_id: str
    status: RunPhase
    verdict: Verdict | None = None
    mean: float | None = None
    expanded_uncertainty: float | None = None  # U = k u
    k: float | None = None
    limit: float | None = None
    location_in: float | None = None  # from the barrel end
    cross_check: Mapping[str, Any] | None = None
    shots: int = 0
    reason: str = ""
    budget_exceeded: bool = False
    details: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))  # RunFinished payload

    @property
    def finished(self) -> bool:
        """Whether the run reached a verdict."""
        return self.status == RunPhase.FINISHED


def _procedure(procedure: str | Path | Procedure) -> Procedure:
    return procedure if isinstance(procedure, Procedure) else Procedure.load(procedure)


def _recorded(store: Store, run_id: str, procedure: Procedure | None) -> tuple[Procedure, BatSpec]:
    """The procedure and bat a run started with (re-validated), for its resume; a run that never
    started (a full disk, a port that would not open) starts with what its RunCreated names
    (rig.resume: a lab's own procedure given again)."""
    from rig.resume import recorded_inputs

    recorded = recorded_inputs(store, run_id, procedure)
    return recorded.procedure, recorded.bat


def _same(given: Any, recorded: Any, what: str, run_id: str) -> None:
    if given is not None and given.model_dump(mode="json") != recorded.model_dump(mode="json"):
        raise ConfigError(
            f"run {run_id} was started with another {what}; resume keeps the recorded one", "resume"
        )


def certify(
    *,
    bat: BatSpec | None = None,
    procedure: str | Path | Procedure | None = None,
    rig: RigSpec,
    store: Store,
    on_event: Callable[[Any], None] | None = None,
    operator: Operator | None = None,
    resume: str | Result | None = None,
    calibration: str | Path | None = None,
    control: RunControl | None = None,
    plan: PlanFactory | None = None,
    accept_overdue: tuple[str, str] | None = None,
) -> Result:
    """Run a certification of `bat` by `procedure` on `rig`, recording it in `store`.

    `procedure`: a built-in name (bbcor, besr, bbs), a TOML path or a Procedure. `on_event` gets each
    of the run's events as it happens, unchanged. `resume` (a run id or a Result) goes on with an
    interrupted run; its bat and procedure are the recorded ones. `calibration` names the model
    calibration for the cross-check (new runs only). `control` pauses or aborts from another thread.
    `plan` is a lab's own procedure composed from rig.plans (default: the standard one); its name is
    recorded in RunStarted, and a resumed run must be given the same plan again. `accept_overdue`
    (who, why) lets instruments past their calibration due date be used, and is recorded.
    Bad input (including a procedure that does not fit the rig or the bat) raises RigError before
    anything is recorded; see `Result` for how a run ends.
    """
    from rig.certification import prepare, run_prepared
    from rig.request import CertifyRequest, Signoff, calibrated

    if not isinstance(rig, RigSpec):
        raise ConfigError("rig must be rig.simulated(SCENE) or rig.from_config(PATH)", "rig")
    run_id = resume.run_id if isinstance(resume, Result) else resume
    if run_id is not None:
        if calibration is not None:
            raise ConfigError("a resumed run keeps the calibration it recorded", "calibration")
        store.run(run_id)  # an unknown run: UnknownRecord naming the ids that exist
        proc, spec = _recorded(store, run_id, None if procedure is None else _procedure(procedure))
        _same(None if procedure is None else _procedure(procedure), proc, "procedure", run_id)
        _same(bat, spec, "bat", run_id)
    else:
        if bat is None or procedure is None:
            raise ConfigError("give bat= and procedure= (or resume= a run id)", "certify")
        if not isinstance(bat, BatSpec):
            raise ConfigError("bat must be a rig.Bat (rig.Bat.load(PATH))", "bat")
        proc, spec = _procedure(procedure), bat
    given: dict[str, Any] = {"plan": plan} if plan is not None else {}  # else the request's default
    if accept_overdue is not None:
        who, why = accept_overdue
        given["accept_overdue"] = Signoff(who, why)
    request = CertifyRequest(
        proc,
        spec,
        lambda measured: calibrated(
            rig.config_for(measured, proc), calibration, "script"
        ),  # with its measured hoop
        run_id=run_id,
        operator=operator or ScriptedOperator(who="script (rig.certify)"),
        subscribers=(on_event,) if on_event is not None else (),
        control=control,
        **given,
    )
    outcome = run_prepared(store, prepare(store, request))
    return _result(store, outcome)


def _result(store: Store, outcome: Any) -> Result:
    v: RunVerdict | None = outcome.verdict
    shots = len(store.entries(outcome.run_id, kinds=[ev.ShotRequested.kind]))
    cross = None if v is None else v.cross_check
    return Result(
        run_id=outcome.run_id,
        status=outcome.status,
        verdict=None if v is None else v.verdict,
        mean=None if v is None else v.mean,
        expanded_uncertainty=None if v is None else v.U,
        k=None if v is None else v.coverage_k,
        limit=None if v is None else v.limit,
        location_in=None if v is None else v.location_in,
        cross_check=None if cross is None else MappingProxyType(dict(cross)),
        shots=shots,
        reason=outcome.reason,
        budget_exceeded=outcome.budget_exceeded,
        details=MappingProxyType({} if v is None else v.to_payload()),
    )


__all__ = [
    "Bat",
    "Result",
    "RigError",
    "RigSpec",
    "RunControl",
    "Verdict",
    "certify",
    "from_config",
    "open_store",
    "simulated",
]
