"""A command imports what it uses and nothing heavier: checked in sys.modules of a fresh process
(not by timing, which a loaded machine would make flaky). The wall-time targets are in
benchmarks/bench_startup.py (`make bench`)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.conftest import rig_env

HEAVY = ("scipy", "matplotlib", "numba", "textual", "pyarrow", "psycopg", "llvmlite")

PROBE = """
import contextlib, io, json, sys
from rig.cli import main
with contextlib.redirect_stdout(io.StringIO()) as out:
    code = main(sys.argv[1:])
loaded = sorted({m.split('.')[0] for m in sys.modules} | {m for m in sys.modules if m.startswith('scipy.')})
print(json.dumps({"code": code, "modules": loaded, "chars": len(out.getvalue())}))
"""


def _loaded(*args: str, cwd: Path) -> tuple[int, set[str], int]:
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=rig_env(),
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.splitlines()[-1])
    return result["code"], set(result["modules"]), result["chars"]


def test_rig_runs_imports_no_numerics_plotting_or_console(store_db: Path, tmp_path: Path) -> None:
    code, modules, chars = _loaded("runs", "--db", str(store_db), cwd=tmp_path)
    assert code == 0 and chars > 0
    assert not modules & {*HEAVY, "numpy", "cryptography"}, sorted(
        modules & {*HEAVY, "numpy", "cryptography"}
    )


@pytest.mark.parametrize("hoop", [["--hoop", "1276"], ["--rigid"]])
def test_rig_model_cor_loads_neither_scipy_integrate_nor_numba(hoop: list[str], tmp_path: Path) -> None:
    code, modules, _ = _loaded("model", "cor", "--speed", "60.8", *hoop, "--json", cwd=tmp_path)
    assert code == 0
    assert "numpy" in modules  # it does solve
    assert not modules & {"scipy.integrate", "scipy.optimize", "matplotlib", "numba", "llvmlite", "textual"}


def test_markdown_report_to_stdout_draws_nothing(store_db: Path, tmp_path: Path) -> None:
    code, modules, chars = _loaded("report", "last", "--db", str(store_db), "--format", "md", cwd=tmp_path)
    assert code == 0 and chars > 1000
    assert not modules & {"scipy.integrate", "matplotlib", "numba", "llvmlite", "textual"}
    assert list(tmp_path.iterdir()) == []


def test_the_probe_sees_a_heavy_import(store_db: Path, tmp_path: Path) -> None:
    """The probe itself can fail: the HTML certificate draws its figures, so matplotlib is loaded."""
    code, modules, _ = _loaded("report", "last", "--db", str(store_db), "--format", "html", cwd=tmp_path)
    assert code == 0 and "matplotlib" in modules
