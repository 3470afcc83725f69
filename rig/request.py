"""A certification as asked (CertifyRequest) and as rehearsed (Prepared): one object from each entry
point (rig.api, `rig certify`, the console) down to the plan's context.

The request carries every option of a run once. rig.certification.prepare gives the bat its measured
hoop, builds the rig config and rehearses the plan, once; rig.certification.run_prepared records and
drives it. Below the application layer only the plan's context (PlanContext) is seen.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

from rig.core.bat import BatSpec
from rig.core.config import Model, RigConfig
from rig.core.errors import ConfigError
from rig.core.events import RunEvent, Subscriber
from rig.protocols.control import Operator, RunControl, ScriptedOperator
from rig.protocols.dryrun import Rehearsal
from rig.protocols.plan import PlanContext, PlanFactory
from rig.protocols.procedure import Procedure
from rig.protocols.state import fold
from rig.protocols.steps import certification, plan_name
from rig.session import RigSession

ConfigFor = Callable[[BatSpec], RigConfig]
"""The rig config for a bat: a simulated rig's bat takes the bat's properties as its true ones."""


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


def calibrated(
    config: RigConfig, calibration: str | Path | None, named_by: Literal["command line", "script"]
) -> RigConfig:
    """`config` naming `calibration` for the cross-check (by `named_by`); unchanged for None."""
    if calibration is None:
        return config
    named = str(Path(calibration).expanduser().resolve())
    return config.model_copy(update={"model": Model(calibration=named, named_by=named_by)})


@dataclass(frozen=True)
class CertifyRequest:
    """One certification as asked. `rig`: its config, or the config for the bat (built once the bat
    has its measured hoop). `run_id`: resume that run. `plan`, `ball`: the plan and its ball terms.
    `operator`, `subscribers`, `control`, `on_open`: who answers, who listens, how a UI steers and
    reads the open devices (none of them changes what the rehearsal sees). `confirm_fire`,
    `review_shots`: the operator confirms each shot, may reject a valid one. `rig_checked`,
    `accept_overdue`: recorded decisions. `sign_simulated`: sign a simulated run with a real key.
    `lab`: the lab identity file (else $RIG_LAB, else the rig config's; rig.core.lab), `tested_by`:
    the operator who performs the test; both recorded when the run is created, for its report.
    """

    procedure: Procedure
    bat: BatSpec
    rig: RigConfig | ConfigFor
    run_id: str | None = None
    plan: PlanFactory = certification
    ball: dict[str, Any] | None = None
    operator: Operator | None = None
    subscribers: tuple[Subscriber, ...] = ()
    control: RunControl | None = None
    on_open: Callable[[RigSession], None] | None = None
    confirm_fire: bool = False
    review_shots: bool = False
    rig_checked: Signoff | None = None
    accept_overdue: Signoff | None = None
    sign_simulated: bool = False
    lab: str | Path | None = None
    tested_by: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "subscribers", tuple(self.subscribers))
        object.__setattr__(self, "tested_by", operator_name(self.tested_by))

    @property
    def options(self) -> dict[str, Any]:
        """The plan's options: the ball terms, when given (recorded in RunStarted)."""
        return {"ball": self.ball} if self.ball is not None else {}

    def config_for(self, bat: BatSpec) -> RigConfig:
        """The rig config for `bat`."""
        return self.rig if isinstance(self.rig, RigConfig) else self.rig(bat)


def operator_name(name: str | None) -> str | None:
    """The operator's name as recorded (stripped), None for none; ConfigError if it is not 1-200
    printable characters."""
    if name is None:
        return None
    if not isinstance(name, str) or not name.strip() or len(name) > 200 or not name.isprintable():
        raise ConfigError("the operator's name: 1-200 printable characters", source="--operator")
    return name.strip()


@dataclass(frozen=True)
class Prepared:
    """A request rehearsed: the bat as it runs (with its measured hoop), the rig config, the rehearsal,
    and the lab identity its report names (rig.core.lab; None: none named)."""

    request: CertifyRequest
    bat: BatSpec
    config: RigConfig
    rehearsal: Rehearsal
    lab: dict[str, Any] | None = None

    def report_meta(self) -> dict[str, Any]:
        """What a new run records for its test report (RunCreated): the lab, who performs the test,
        who answers the prompts, and whether the rig is simulated."""
        return {
            "lab": self.lab,
            "tested_by": self.request.tested_by,
            "answered_by": getattr(self.operator, "who", "operator"),
            "simulated": self.config.simulated,
        }

    @property
    def operator(self) -> Operator:
        """Who answers the prompts (a script answering yes, if the request names nobody)."""
        return self.request.operator or ScriptedOperator()

    def steered(
        self,
        *,
        operator: Operator,
        control: RunControl,
        subscribers: tuple[Subscriber, ...],
        on_open: Callable[[RigSession], None] | None = None,
    ) -> Prepared:
        """The same rehearsed run, answered, steered and watched by a UI that exists only now."""
        how = replace(
            self.request, operator=operator, control=control, subscribers=subscribers, on_open=on_open
        )
        return replace(self, request=how)

    def context(self, past: list[RunEvent]) -> PlanContext:
        """The plan's context for a session that goes on from the record `past`."""
        r = self.request
        return PlanContext(
            r.procedure,
            self.bat,
            self.config,
            fold(past),
            who=getattr(self.operator, "who", "operator"),
            confirm_fire=r.confirm_fire,
            review_shots=r.review_shots,
            rig_check=None if r.rig_checked is None else r.rig_checked.as_dict(),
            plan_name=plan_name(r.plan),
            options=r.options,
        )
