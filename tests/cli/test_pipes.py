"""Output sent to a pipe or a file: whole lines (no wrapping at 80 columns), no terminal dumps."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from rig.cli import main
from tests.cli.conftest import GOOD_BAT, QUICK_PROCEDURE, rig


def test_certify_in_a_pipe_keeps_each_line_whole_with_its_indent(tmp_path: Path) -> None:
    """The summary's decision rule and the model's note were wrapped at 80 columns, losing the indent
    (`guarded acceptance: PASS if` / `mean + 2 u <= limit`)."""
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    args = ("certify", "--procedure", "proc.toml", "--bat", "bat.toml", "--sim", "ideal", "--db", "r.db")
    done = rig(*args, cwd=tmp_path)
    assert done.returncode in (0, 1), done.stderr
    record = json.loads(rig("report", "last", "--db", "r.db", "--json", cwd=tmp_path).stdout)
    rule = record["verdict"]["decision_rule"]
    lines = done.stdout.splitlines()
    assert any(line.startswith("  ") and line.endswith(f"; {rule}") for line in lines), done.stdout
    note = record["cross_check"]["note"]
    assert len(note) > 80 and any(line.startswith("  model ") and line.endswith(note) for line in lines)


class _Terminal(io.StringIO):
    """Standard output that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_an_html_report_is_not_dumped_on_a_terminal(store_db: Path) -> None:
    """200 KB of HTML on a terminal helps nobody: one line that names --output, exit 2."""
    out, err = _Terminal(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["report", "last", "--db", str(store_db), "--format", "html"])
    assert code == 2 and out.getvalue() == ""
    (line,) = err.getvalue().splitlines()
    assert "--output" in line and "terminal" in line
