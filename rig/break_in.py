"""The accelerated break-in (ABI) as the entry points name it: `--procedure abi` is the procedure the
ABI's stages are measured by (protocols/abi.toml: BBCOR) run by the ABI plan (rig.protocols.abi); a
recorded run's plan is found again by the name its RunStarted (or RunCreated) records."""

from __future__ import annotations

from rig.core import events as ev
from rig.core.errors import ConfigError
from rig.protocols.abi import ROLE as ABI_ROLE
from rig.protocols.abi import abi
from rig.protocols.abi_rules import AbiRules
from rig.protocols.plan import PlanFactory
from rig.protocols.procedure import Procedure
from rig.protocols.steps import certification

ABI = "abi"  # the name `rig certify --procedure` takes
ABI_PLAN = ev.ABI_PLAN  # its recorded name: rig.protocols.abi.abi (plan_name(abi))


__all__ = ["ABI", "ABI_PLAN", "ABI_ROLE", "load_procedure", "recorded_plan"]


def load_procedure(name: str) -> tuple[Procedure, PlanFactory]:
    """The procedure and plan `--procedure NAME` runs: the ABI's, else the procedure (built-in or a
    file) with the standard steps."""
    if name == ABI:
        return Procedure.load(AbiRules.load().procedure), abi
    return Procedure.load(name), certification


def recorded_plan(name: str | None, run_id: str) -> PlanFactory:
    """The plan a run recorded (None: the standard steps); a lab's own plan is not known here."""
    if name is None:
        return certification
    if name == ABI_PLAN:
        return abi
    raise ConfigError(
        f"run {run_id} was started with the lab's own plan {name}: resume it with that plan from "
        "Python (rig.certify(..., resume=RUN, plan=...))",
        source="--resume",
    )
