"""The blocking work behind the run screen: a run's one rehearsal, the run and the model's prediction.

The set-up screen rehearses a new run (prepare_job) to show its problems on the form; the run and the
prediction are called from thread workers only. None of them touches the UI (results are returned).
"""

from __future__ import annotations

from dataclasses import dataclass

from rig.break_in import ABI
from rig.certification import Outcome, prepare, run_prepared
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.core.errors import ConfigError, RigError
from rig.core.events import Subscriber
from rig.protocols.control import RunControl
from rig.protocols.evaluate import cross_check, run_calibration
from rig.protocols.procedure import Procedure
from rig.request import CertifyRequest, ConfigFor, Prepared
from rig.resume import recorded_plan_name
from rig.store import Store
from rig.tui.operator import ConsoleOperator
from rig.tui.rigs import ConsoleSettings, RigChoice, RunJob

NO_BREAK_IN = (
    "the console cannot run the accelerated break-in (abi) yet: it has no rolling prompts; run it with "
    "rig certify --procedure abi, and resume it with rig certify --resume RUN"
)


def refuse_break_in(procedure: str) -> None:
    """ConfigError (one line) for the accelerated break-in, which the console cannot run yet."""
    if procedure == ABI:
        raise ConfigError(NO_BREAK_IN, source="procedure")


def _refuse_break_in_run(store: Store, run_id: str) -> None:
    """ConfigError (one line) for resuming a run the accelerated break-in's plan started."""
    if recorded_plan_name(store, run_id) == ev.ABI_PLAN:
        raise ConfigError(NO_BREAK_IN, source="resume")


@dataclass(frozen=True)
class JobResult:
    """How a run ended: an outcome, or the failure that stopped it; `run_id` to resume it."""

    outcome: Outcome | None
    failure: str
    run_id: str | None


def console_request(
    procedure: Procedure,
    bat: BatSpec,
    rig: RigConfig | ConfigFor,
    run_id: str | None = None,
    tested_by: str | None = None,
) -> CertifyRequest:
    """A run from the console: the operator confirms each shot and reviews each valid one;
    `tested_by`: the name the set-up screen asked for (recorded with a new run)."""
    return CertifyRequest(
        procedure, bat, rig, run_id=run_id, confirm_fire=True, review_shots=True, tested_by=tested_by
    )


def prepare_job(
    settings: ConsoleSettings,
    procedure: Procedure,
    bat: BatSpec,
    choice: RigChoice,
    tested_by: str | None = None,
) -> RunJob:
    """A new run's job, rehearsed (rig.certification.prepare: the bat's measured hoop, the rig, the
    dry run, the lab file); raises RigError naming every problem, so that the set-up form can show it."""

    def config_for(measured: BatSpec) -> RigConfig:  # a simulated rig loads the procedure's balls
        return choice.config(measured, procedure)

    with Store.open(settings.db, clock=settings.clock) as store:
        prepared = prepare(store, console_request(procedure, bat, config_for, tested_by=tested_by))
    return RunJob(procedure, prepared.bat, prepared.config, choice.label, rig=choice, prepared=prepared)


def _prepared(store: Store, job: RunJob) -> Prepared:
    """The job's rehearsal: the set-up's for the new run it was made for, else one made now (a resume)."""
    if job.prepared is not None and job.prepared.request.run_id == job.run_id:
        return job.prepared
    if job.run_id is not None:
        _refuse_break_in_run(store, job.run_id)
    return prepare(store, console_request(job.procedure, job.bat, job.config, job.run_id))


def run_job(
    settings: ConsoleSettings,
    job: RunJob,
    operator: ConsoleOperator,
    control: RunControl,
    on_event: Subscriber,
) -> JobResult:
    """Run (or resume) the job to its end; every error comes back as a message, never raised."""
    run_id = job.run_id
    try:
        with settings.device_lock, Store.open(settings.db, clock=settings.clock) as store:
            before = {r.run_id for r in store.runs()}
            try:
                steered = _prepared(store, job).steered(
                    operator=operator, control=control, subscribers=(on_event,), on_open=operator.attach
                )
                outcome = run_prepared(store, steered)
            finally:  # a run that failed is resumed by its id, even one that never started
                run_id = next((r.run_id for r in store.runs() if r.run_id not in before), run_id)
    except RigError as exc:
        return JobResult(None, str(exc), run_id)
    except Exception as exc:  # a bug must still reach the screen, not kill the console
        return JobResult(None, f"unexpected {type(exc).__name__}: {exc}", run_id)
    return JobResult(outcome, "", outcome.run_id)


def predict(job: RunJob, moi_kgm2: float, location_in: float) -> tuple[float | None, str]:
    """The collision model's metric for this bat at the target speed, and a short note."""
    p, bat = job.procedure, job.bat
    try:
        q = bat.impact_from_pivot_m(location_in)
        calibration = run_calibration(p, job.config)  # the one the verdict will use, if any
        cc = cross_check(p, bat, p.target_speed_m_s, q, moi_kgm2, 0.0, calibration=calibration)
    except Exception as exc:  # the model is a help, never a reason to stop the run
        return None, f"model failed: {exc}"
    if cc["predicted"] is None:
        return None, "no hoop frequency: no model"
    # the note shares one panel line (about 38 columns at 80x24) with "model 0.4958 "
    if not cc.get("calibrated"):
        return float(cc["predicted"]), f"uncalibrated, at {location_in:g} in"
    lo, hi = cc["interval"]
    return float(cc["predicted"]), f"calibrated {lo:.3f}-{hi:.3f}"
