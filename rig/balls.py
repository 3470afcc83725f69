"""Test a ball lot on the rig: store, devices, the ball test's plan and its executor wired together.

Run like a certification (rig.certification): rehearsed first (a dry run of what is left), every
persisted event committed before the plan goes on, one runner per run, any error recorded as
the run's interruption (resumable at the next slot), the run sealed and signed at its end. What the
clamp holds comes from the procedure (its [target]), never from the simulator: a `--sim` rig is
built with that target clamped (rig.session.sim_config), a real rig is told by the operator.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace
from typing import Any

from protocols.ball_eval import lot_result
from protocols.ball_procedure import BallProcedure
from protocols.ball_steps import BallContext, ball_test
from protocols.control import Operator, RunControl, ScriptedOperator
from protocols.dryrun import Rehearsal, rehearse
from protocols.executor import Executor, LiveRig
from protocols.state import fold
from rig import __version__
from rig.certification import Emit, Outcome, _running, _traffic_drain, drive, history, register_item
from rig.core import events as ev
from rig.core.ball import BALL_TESTS, BallLot
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RigError
from rig.core.events import RunEvent, Subscriber
from rig.keys import recorded_rig, signing_for
from rig.session import RigSession
from rig.store import Store


def recorded_test(store: Store, run_id: str) -> tuple[BallProcedure, BallLot]:
    """The procedure and lot a ball-test run recorded when it started."""
    started = store.entries(run_id, kinds=[ev.RUN_STARTED])
    if not started or started[0].payload.get("test") not in BALL_TESTS:
        raise ConfigError(f"run {run_id} is not a started ball test", source="--resume")
    payload = started[0].payload
    return BallProcedure.model_validate(payload["procedure"]), BallLot.model_validate(payload["lot"])


def rehearse_test(
    procedure: BallProcedure, lot: BallLot, config: RigConfig, past: list[RunEvent] | None = None
) -> Rehearsal:
    """A dry run of the test (or of what is left of a resumed one): nothing armed, moved or stored."""
    return rehearse(procedure, None, config, ball_test, past, context=BallContext, lot=lot)  # type: ignore[arg-type]


def run_ball_test(
    store: Store,
    procedure: BallProcedure,
    lot: BallLot,
    config: RigConfig,
    *,
    run_id: str | None = None,
    operator: Operator | None = None,
    subscribers: Iterable[Subscriber] = (),
    control: RunControl | None = None,
) -> Outcome:
    """Run (or with `run_id`, resume) a ball test of `lot`; returns its outcome.

    The lot must be registered (Store.register_lot). The target is registered as what the clamp
    holds (the run's `bat`), so that the store's runs keep naming what was struck.
    """
    resuming = run_id is not None
    if run_id is not None:
        _running(store, run_id, "--resume")
    registered = store.ball_lots().get(lot.id)
    if registered is None:
        raise ConfigError(
            f"ball lot {lot.id} is not registered: rig balls register LOT.toml first", source="--lot"
        )
    if registered != lot:
        raise ConfigError(f"ball lot {lot.id} is registered with other values", source="--lot")
    past = history(store, run_id) if run_id is not None else None
    problems = rehearse_test(procedure, lot, config, past).problems
    if problems:
        raise ConfigError("; ".join(problems), source="dry run")
    identity = config.identity_record(__version__)
    rig = (recorded_rig(store, run_id) if run_id else None) or str(identity["name"])
    signing = signing_for(store, rig, simulated=config.simulated)  # never a real rig's key for a simulation
    if run_id is None:
        target = procedure.target
        refusal = ConfigError(f"target {target.id} is registered with other properties", source="procedure")
        register_item(store, target.id, target.spec(), refusal)
        meta = {"procedure": procedure.name, "rig": identity, "lot": lot.id, "test": procedure.test}
        run_id = store.create_run(procedure.test, target.id, meta)
    named = ev.RigNamed(name=rig, simulated=config.simulated, signing=signing.note)

    def start(session: RigSession, past: list[RunEvent], emit: Emit) -> tuple[Executor, Callable[[], Any]]:
        operator_ = operator or ScriptedOperator()
        ctx = BallContext(
            procedure,  # type: ignore[arg-type]
            None,  # type: ignore[arg-type]
            config,
            fold(past),
            who=getattr(operator_, "who", "operator"),
            lot=lot,
        )
        executor = Executor(
            ctx,
            LiveRig(session.cannon, session.gates, session.clamp),
            emit,
            operator_,
            control,
            _traffic_drain(session),
        )
        return executor, lambda: executor.run(ball_test)

    outcome = drive(
        store,
        run_id,
        config,
        list(subscribers),
        signing.signer,
        start,
        resuming=resuming,
        what="ball test",
        named=named,
    )
    return replace(outcome, signing=signing.note)


def recomputed_problems(store: Store) -> list[str]:
    """Every finished ball test whose recorded lot result differs from the one its shots give.

    The chain shows a run was not changed after it was written; this shows that what it concluded
    follows from its shots (the same derivation, protocols.ball_eval.lot_result).
    """
    problems = []
    for run in store.runs():
        if run.procedure not in BALL_TESTS or run.status != "finished":
            continue
        events = ev.parse_log(store.entries(run.run_id))
        state = fold(events)
        recorded = (state.verdict or {}).get("lot_result")
        if recorded is None:
            continue
        try:
            procedure, lot = recorded_test(store, run.run_id)
            again = lot_result(procedure, lot.id, state).model_dump(mode="json", exclude={"run_id"})
        except (RigError, ValueError, KeyError) as exc:
            problems.append(f"run {run.run_id}: its lot result cannot be recomputed from its shots ({exc})")
            continue
        if not _same(again, recorded):
            problems.append(
                f"run {run.run_id}: the recorded lot result of lot {lot.id} is not what its shots give "
                f"(recorded {recorded.get('quantity')} {recorded.get('mean')!r}, "
                f"recomputed {again['mean']!r})"
            )
    return problems


# the terms a certification derives from its lot's results (the rest is the run's own: balls, law)
DERIVED_TERMS = (
    "wear_measured",
    "conditions_measured",
    "plate_cor",
    "wear_per_hit",
    "wear_per_hit_u",
    "sd_between_balls",
    "cor_per_c",
    "cor_per_c_u",
    "cor_per_pct_rh",
    "cor_per_pct_rh_u",
    "air_cov",
    "temp_c",
    "rh_pct",
)


def ball_terms_problems(store: Store) -> list[str]:
    """Every certification whose recorded ball terms are not what its lot's named results give.

    A run records the run ids of the ball-cor results its terms rest on (BallTerms.results); the
    terms are derived again from exactly those results (each checked against its own shots by
    recomputed_problems) and the lot as registered. Runs recorded before the ids were are skipped.
    """
    from protocols.ball_terms import BallTerms, terms_from_lot

    problems: list[str] = []
    lots = store.ball_lots()
    for run in store.runs():
        if run.procedure in BALL_TESTS:
            continue
        started = store.entries(run.run_id, kinds=[ev.RUN_STARTED])
        recorded = (started[0].payload.get("ball") if started else None) or {}
        if not recorded.get("lot") or not recorded.get("results"):
            continue
        lot_id, ids = recorded["lot"], list(recorded["results"])
        if lot_id not in lots:
            problems.append(f"run {run.run_id}: its ball terms name lot {lot_id}, which is not registered")
            continue
        by_id = {r.run_id: r for r in store.ball_lot(lot_id)[1]}
        missing = [i for i in ids if i not in by_id]
        if missing:
            problems.append(
                f"run {run.run_id}: its ball terms rest on ball-cor run {missing[0]}, which the store does"
                f" not hold as a finished test of lot {lot_id}"
            )
            continue
        again = terms_from_lot(lots[lot_id], [by_id[i] for i in ids], recorded.get("law"))
        want = BallTerms.model_validate(recorded).model_dump(mode="json", include=set(DERIVED_TERMS))
        got = again.model_dump(mode="json", include=set(DERIVED_TERMS))
        bad = [k for k in DERIVED_TERMS if not _same(got[k], want[k])]
        if bad:
            problems.append(
                f"run {run.run_id}: its recorded ball terms are not what lot {lot_id}'s results give"
                f" ({bad[0]}: recorded {want[bad[0]]!r}, derived {got[bad[0]]!r})"
            )
    return problems


def _same(a: Any, b: Any, rel: float = 1e-9) -> bool:
    """Equal JSON values, floats to a relative tolerance (a recomputation may round differently)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k], rel) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y, rel) for x, y in zip(a, b, strict=True))
    if isinstance(a, float | int) and isinstance(b, float | int) and not isinstance(a, bool):
        return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)
    return a == b
