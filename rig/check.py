"""Run the lab's check procedure on its reference bat: a certification's machinery, its own plan.

A check session (rig.protocols.check) is asked, rehearsed and recorded as a certification is
(rig.certification: one request, one rehearsal, every event committed at its commit point,
sealed and signed), with the run's kind `check` so that the control charts (rig.quality) find it.
It is never refused by the charts' signals: the check is how a lab sees whether the rig is back.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from rig.certification import Outcome, prepare, run_prepared
from rig.core.errors import ConfigError
from rig.protocols.check import KIND, check_session
from rig.protocols.procedure import BUILTIN_DIR, Procedure
from rig.request import CertifyRequest, Prepared
from rig.store import Store

__all__ = ["KIND", "PROCEDURE", "check_procedure", "prepare_check", "run_check"]

PROCEDURE = BUILTIN_DIR / "check.toml"


def check_procedure(path: str | Path | None = None, hits: int | None = None) -> Procedure:
    """The check procedure (protocols/check.toml, or a lab's own file), with `hits` valid hits."""
    procedure = Procedure.load(path or PROCEDURE)
    if hits is None:
        return procedure
    if not 2 <= hits <= 50:
        raise ConfigError(f"{hits} hits: a check session needs 2-50 (its spread is charted)", source="--hits")
    return procedure.model_copy(update={"hits": procedure.hits.model_copy(update={"valid_hits": hits})})


def prepare_check(store: Store, request: CertifyRequest) -> Prepared:
    """The one rehearsal of a check session (its plan made check_session; never refused by the
    charts' signals)."""
    return prepare(store, replace(request, plan=check_session), gated=False)


def run_check(store: Store, prepared: Prepared) -> Outcome:
    """Record and run a rehearsed check session (kind `check` in the store)."""
    return run_prepared(store, prepared, kind=KIND)
