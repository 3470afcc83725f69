"""Every built-in procedure and metric states its basis (the bat's constraint), the same in both, and
nothing cites ASTM F2219-23 as the source of a pivoted formula: F2219 is cited for its cannon method,
F2219-23 only as the unconstrained basis the pivoted one is not. The certificate says so."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path

import pytest

from rig.cli import main
from rig.measure import registry
from rig.protocols.procedure import BUILTIN, Procedure

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
# the ways F2219 may be named: its cannon method, or F2219-23's unconstrained basis as the one not used
ALLOWED = (
    r"(?:cannon )?(?:test )?method of ASTM F2219",
    r"not F2219-23's unconstrained (?:one|basis|formula)",
    r"not unconstrained \(ASTM F2219-23\)",
)


def _cites_f2219_for_a_formula(text: str) -> bool:
    for pattern in ALLOWED:
        text = re.sub(pattern, "", text)
    return "F2219" in text


@pytest.mark.parametrize("name", BUILTIN)
def test_each_built_in_procedure_states_its_metrics_basis(name: str) -> None:
    p = Procedure.load(name)
    assert p.metric.basis, f"{p.standard} states no basis"
    assert p.basis is not None and p.metric.basis.startswith(f"{p.basis}:"), (p.basis, p.metric.basis)
    assert not _cites_f2219_for_a_formula(p.edition), p.edition
    assert not _cites_f2219_for_a_formula(p.metric.definition), p.metric.definition


def test_every_built_in_metric_states_a_basis_and_no_pivoted_one_cites_f2219_23() -> None:
    for name in registry.BUILTIN_METRICS:
        entry = registry.find(name)
        assert entry is not None and entry.basis.split(":", 1)[0] in ("pivoted", "unconstrained"), name
        assert not _cites_f2219_for_a_formula(entry.definition + entry.basis), name


def test_the_rule_catches_a_bare_citation() -> None:
    assert _cites_f2219_for_a_formula("NCAA BBCOR; metric per ASTM F2219")
    assert not _cites_f2219_for_a_formula(
        "cannon test method of ASTM F2219; not F2219-23's unconstrained one"
    )


@pytest.mark.parametrize("run", ["bbcor_lot", "besr", "bbs"])
def test_the_certificate_names_the_pivoted_basis_and_not_f2219_23s(tmp_path: Path, run: str) -> None:
    """An old record (its recorded edition as it was) still shows the basis and that it is not F2219-23's."""
    runs = json.loads((FIXTURES / "log-8802354.runs.json").read_text())
    db = tmp_path / "r.db"
    shutil.copyfile(FIXTURES / "log-8802354.db", db)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["report", runs[run], "--format", "md", "--db", str(db)]) == 0
    row = next(
        line for line in out.getvalue().splitlines() if line.startswith("| basis (the bat's constraint)")
    )
    assert "| pivoted: " in row and "rig's pivot" in row and "; not unconstrained (ASTM F2219-23" in row
