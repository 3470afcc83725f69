"""Progress bars go to stderr and only to a terminal: a pipe or a file gets none."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
from pathlib import Path

from tests.cli.conftest import rig, rig_env


def _stderr_on_a_terminal(*args: str, cwd: Path, module: str = "rig.cli") -> tuple[int, str, str]:
    """`rig ARGS` (or another command's `python -m MODULE ARGS`) with stderr on a pseudo-terminal,
    stdout to a file: exit status, stdout, what the terminal got."""
    leader, follower = pty.openpty()
    out_file = cwd / "stdout.txt"
    with out_file.open("wb") as sink:
        proc = subprocess.Popen(
            [sys.executable, "-m", module, *args],
            cwd=cwd,
            env=rig_env(TERM="xterm", COLUMNS="100"),
            stdout=sink,
            stderr=follower,
        )
    os.close(follower)
    seen = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the terminal closed with the process
            break
        if not chunk:
            break
        seen += chunk
    os.close(leader)
    code = proc.wait(timeout=300)
    out = out_file.read_text(encoding="utf-8")
    out_file.unlink()
    return code, out, seen.decode(errors="replace")


def test_a_report_shows_a_bar_on_a_terminal_only(store_db: Path, tmp_path: Path) -> None:
    args = ("report", "last", "--db", str(store_db), "--format", "html")
    code, page, terminal = _stderr_on_a_terminal(*args, cwd=tmp_path)
    assert code == 0 and page.startswith("<!DOCTYPE html>")
    assert "drawing its figures" in terminal  # the bar, on stderr
    piped = rig(*args, cwd=tmp_path)
    assert piped.returncode == 0 and piped.stdout == page  # the same document, and no bar in it
    assert "drawing" not in piped.stderr and "\x1b[" not in piped.stderr


def test_the_accuracy_study_counts_its_solves_on_a_terminal(tmp_path: Path) -> None:
    code, _, terminal = _stderr_on_a_terminal("accuracy", "--quick", "--json", cwd=tmp_path, module="studies")
    assert code == 0 and "solves timed" in terminal
