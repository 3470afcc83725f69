"""Test a ball lot on the rig: store, devices, the ball test's plan and its executor wired together.

Run like a certification (rig.certification): rehearsed first (a dry run of what is left), every
persisted event committed at its commit point (rig.store.RunWriter), one runner per run, any error recorded as
the run's interruption (resumable at the next slot), the run sealed and signed at its end. What the
clamp holds comes from the procedure (its [target]), never from the simulator: a `--sim` rig is
built with that target clamped (rig.session.sim_config), a real rig is told by the operator.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from rig.ball_rules import refuse_other_balls
from rig.certification import (
    Emit,
    NewRun,
    Outcome,
    Signoff,
    _running,
    history,
    live_executor,
    record_run,
)
from rig.core import events as ev
from rig.core.ball import BALL_TESTS, BallLot
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RigError
from rig.core.events import RunEvent, Subscriber
from rig.protocols.ball_eval import lot_result
from rig.protocols.ball_procedure import BallProcedure
from rig.protocols.ball_steps import BallContext, ball_test
from rig.protocols.control import Operator, RunControl, ScriptedOperator
from rig.protocols.dryrun import Rehearsal, rehearse
from rig.protocols.executor import Executor
from rig.protocols.state import fold
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
    accept_overdue: Signoff | None = None,
) -> Outcome:
    """Run (or with `run_id`, resume) a ball test of `lot`; returns its outcome.

    The lot must be registered (Store.register_lot). The target is registered as what the clamp
    holds (the run's `bat`), so that the store's runs keep naming what was struck. The instruments
    are identified and their calibrations checked as a certification's are (`accept_overdue`).
    """
    override = None if accept_overdue is None else accept_overdue.as_dict()
    if run_id is not None:
        _running(store, run_id, "--resume")
    registered = store.ball_lots().get(lot.id)
    if registered is None:
        raise ConfigError(
            f"ball lot {lot.id} is not registered: rig balls register LOT.toml first", source="--lot"
        )
    if registered != lot:
        raise ConfigError(f"ball lot {lot.id} is registered with other values", source="--lot")
    if run_id is None:
        refuse_other_balls(lot, procedure.name, procedure.ball)
    past = history(store, run_id) if run_id is not None else None
    problems = rehearse_test(procedure, lot, config, past).problems
    if problems:
        raise ConfigError("; ".join(problems), source="dry run")
    target = procedure.target
    refusal = ConfigError(f"target {target.id} is registered with other properties", source="procedure")
    meta = {"procedure": procedure.name, "lot": lot.id, "test": procedure.test}
    new = NewRun(procedure.test, target.id, target.spec(), refusal, meta)

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
        executor = live_executor(session, ctx, emit, operator_, control)
        return executor, lambda: executor.run(ball_test)

    # never a real rig's key for a simulation (record_run: sign_simulated False)
    return record_run(
        store, config, run_id or new, list(subscribers), start, what="ball test", override=override
    )


def recomputed_problems(store: Store) -> list[str]:
    """Every finished ball test whose recorded lot result differs from the one its shots give.

    The chain shows a run was not changed after it was written; this shows that what it concluded
    follows from its shots (the same derivation, rig.protocols.ball_eval.lot_result).
    """
    problems = []
    for run in store.runs():
        if run.procedure not in BALL_TESTS or run.status != "finished":
            continue
        events = ev.parse_log(store.entries(run.run_id))
        state = fold(events)
        recorded = None if state.verdict is None else state.verdict.lot_result
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

WALL_TERMS = (
    "wall_cor",
    "wall_cor_u",
    "wall_cor_run",
    "wall_cor_hit",
    "wall_cor_temp_c",
    "wall_cor_rh_pct",
)  # the ball COR a BPF divides by, since BPF


def ball_terms_problems(store: Store) -> list[str]:
    """Every certification whose recorded ball terms are not what its lot's results give.

    A run records the run ids of the ball-cor results its terms rest on (BallTerms.results): they
    must be every ball-cor test of the lot finished before the run started, and the terms are
    derived again from exactly those (each checked against its own shots by recomputed_problems)
    and the lot as registered; a law taken from the lot must be one the lot recorded. A run whose
    lot is not in this store (e.g. copied by `rig sync`, which copies no lots) cannot be derived
    here and is left to the store it came from; runs recorded before the ids were are skipped.
    """
    problems: list[str] = []
    lots = store.ball_lots()
    finished: dict[str, list[tuple[int, Any]]] = {}  # lot -> (RunFinished seq, result), read once
    for run in store.runs():
        if run.procedure in BALL_TESTS:
            continue
        started = store.entries(run.run_id, kinds=[ev.RUN_STARTED])
        recorded = (started[0].payload.get("ball") if started else None) or {}
        if not recorded.get("lot") or "results" not in recorded or recorded["lot"] not in lots:
            continue
        lot = lots[recorded["lot"]]
        if lot.id not in finished:
            finished[lot.id] = [
                (store.entries(r.run_id, kinds=[ev.RUN_FINISHED])[0].seq, r)
                for r in store.ball_lot(lot.id)[1]
                if r.procedure == "ball-cor" and r.wear_per_hit is not None
            ]
        problem = _terms_problem(store, lot, finished[lot.id], recorded, started[0].seq)
        if problem:
            problems.append(f"run {run.run_id}: {problem}")
    return problems


def _terms_problem(
    store: Store, lot: Any, tests: list[tuple[int, Any]], recorded: dict[str, Any], started_seq: int
) -> str | None:
    """What is wrong with one run's recorded terms of `lot` (None: they are what its results give);
    `tests`: the lot's ball-cor results with the seq of the RunFinished that holds each."""
    from pydantic import ValidationError

    from rig.protocols.ball_terms import BallTerms, terms_from_lot

    try:
        terms = BallTerms.model_validate(recorded)
    except ValidationError as exc:
        return f"its recorded ball terms are unreadable ({exc.errors()[0]['msg']})"
    before = [r for seq, r in tests if seq < started_seq]
    expected = [r.run_id for r in before]
    if list(terms.results) != expected:
        named, due = (", ".join(i[:12] for i in ids) or "none" for ids in (terms.results, expected))
        return f"its ball terms rest on ball-cor runs {named}, not on lot {lot.id}'s tests before it ({due})"
    if terms.law_from and terms.law_from.startswith("lot ") and terms.law_sha256 is not None:
        laws = {w.sha256: w for w in store.ball_laws(lot.id) if w.seq < started_seq}
        if terms.law_sha256 not in laws:
            return f"its ball law (sha256 {terms.law_sha256[:12]}) is not one lot {lot.id} had recorded"
    again = terms_from_lot(lot, before, recorded.get("law"))
    derived = DERIVED_TERMS + tuple(k for k in WALL_TERMS if k in recorded)  # older runs lack them
    want = terms.model_dump(mode="json", include=set(derived))
    got = again.model_dump(mode="json", include=set(derived))
    bad = [k for k in derived if not _same(got[k], want[k])]
    if bad:
        return (
            f"its recorded ball terms are not what lot {lot.id}'s results give"
            f" ({bad[0]}: recorded {want[bad[0]]!r}, derived {got[bad[0]]!r})"
        )
    return None


def _same(a: Any, b: Any, rel: float = 1e-9) -> bool:
    """Equal JSON values, floats to a relative tolerance (a recomputation may round differently)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k], rel) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y, rel) for x, y in zip(a, b, strict=True))
    if isinstance(a, float | int) and isinstance(b, float | int) and not isinstance(a, bool):
        return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)
    return a == b
