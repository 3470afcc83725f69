"""Fixtures for the command tests: a record store holding one short simulated certification, and
`rig` run as a separate process (its imports, its files, its output to a pipe)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE, run_cli

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def store_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A store with one finished run (a quick BBCOR procedure on the ideal simulated rig)."""
    folder = tmp_path_factory.mktemp("cli-store")
    (folder / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (folder / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    db = folder / "records.db"
    argv = ["certify", "--procedure", str(folder / "proc.toml"), "--bat", str(folder / "bat.toml")]
    result = run_cli([*argv, "--sim", "ideal", "--db", str(db)], db)
    assert result.code in (0, 1), result.err
    return db


def rig_env(**extra: str) -> dict[str, str]:
    """The environment of a `rig` process: this checkout importable, no RIG_DB unless given."""
    env = {k: v for k, v in os.environ.items() if k != "RIG_DB"}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.update(extra)
    return env


def rig(
    *args: str, cwd: Path | None = None, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """`rig ARGS` as its own process, stdout and stderr to pipes (not a terminal)."""
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd or ROOT,
        env=env or rig_env(),
        timeout=300,
    )
