"""What a newcomer meets first: the README's quick start and the `make demo` that it runs."""

from __future__ import annotations

import ast
import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from rig.cli import main
from rig.store import Store
from tests.unit.clirun import QUICK_PROCEDURE

ROOT = Path(__file__).resolve().parents[2]


def _section(title: str) -> str:
    """The README's `## title` section."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    match = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## )", text, flags=re.S | re.M)
    assert match, title
    return match.group(1)


def _recipe(target: str) -> str:
    """The Makefile's recipe lines for `target`."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    match = re.search(rf"^{target}:.*\n((?:\t.*\n|\n)*)", text, flags=re.M)
    assert match, target
    return match.group(1)


def test_the_quick_start_says_how_to_run_rig_after_make_demo() -> None:
    """`rig` lives in .venv/bin, which is not on PATH: the README and the demo's last lines say how to
    run it, and that the demo's records are in out/demo.db (a bare `rig runs` reads rig-records.db)."""
    quick = _section("Quick start")
    assert ". .venv/bin/activate" in quick and ".venv/bin/rig" in quick
    assert "rig runs --db out/demo.db" in quick
    said = " ".join(line for line in _recipe("demo").splitlines() if "echo" in line)
    assert ". .venv/bin/activate" in said and "rig runs --db out/demo.db" in said


def test_rig_help_lists_the_everyday_commands_first(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    listed = re.findall(r"^    (\w[\w-]*) ", text.split("COMMAND\n", 2)[-1], flags=re.M)
    assert listed[:4] == ["certify", "runs", "report", "verify"], listed


def test_ending_a_run_says_so_on_stdout_without_the_error_prefix(tmp_path: Path) -> None:
    """`rig certify --end` succeeds (exit 0): its line goes to stdout, and not as `rig: ...`."""
    db = tmp_path / "r.db"
    with Store.open(db) as store:
        store.register_bat("B1", {"id": "B1"})
        run_id = store.create_run("bbcor", "B1", {})
    out, err = io.StringIO(), io.StringIO()
    argv = ["certify", "--end", run_id[:8], "--who", "ann", "--why", "bat cracked", "--db", str(db)]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert main(argv) == 0
    assert err.getvalue() == ""
    assert out.getvalue() == f"run {run_id} ended without a verdict by ann: bat cracked\n"


def _code_blocks(text: str) -> list[str]:
    return re.findall(r"^```[a-z]*\n(.*?)^```", text, flags=re.S | re.M)


def test_the_readme_has_a_runnable_model_cor_example(capsys: pytest.CaptureFixture[str]) -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = [
        ln for block in _code_blocks(readme) for ln in block.splitlines() if ln.startswith("rig model cor ")
    ]
    assert lines, "no `rig model cor` example in a README code block"
    for line in lines:
        argv = shlex.split(line.split("#", 1)[0])[1:]
        assert main(argv) == 0, line
        assert "cor" in capsys.readouterr().out


def test_no_operator_message_names_a_python_call() -> None:
    """Messages are for lab operators: "call reconnect()" tells them nothing they can do."""
    call = re.compile(r"\b[A-Za-z_][\w.]*\(\)")
    found = []
    for top in ("rig", "drivers", "protocols", "simulators"):
        for path in sorted((ROOT / top).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            docs = {
                id(node.body[0].value)
                for node in ast.walk(tree)
                if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
                and node.body
                and isinstance(node.body[0], ast.Expr)
            }
            for node in ast.walk(tree):
                if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
                    sql = re.search(r"\b(SELECT|CREATE|EXECUTE FUNCTION)\b", node.value)
                    if call.search(node.value) and not sql:
                        found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value!r}")
    assert not found, found


def test_the_readme_keys_sequence_signs_a_simulated_run(tmp_path: Path) -> None:
    """The README's `rig keys` lines, run as written (the store in tmp_path, a quick procedure)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    (block,) = [b for b in _code_blocks(_section("Signing simulated runs")) if "rig keys create" in b]
    (tmp_path / "quick.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    results = []
    for line in block.splitlines():
        argv = shlex.split(line.split("#", 1)[0])[1:]
        argv = [str(tmp_path / "demo.db") if a == "out/demo.db" else a for a in argv]
        argv = [str(tmp_path / "quick.toml") if a == "bbcor" else a for a in argv]
        argv = [str(ROOT / a) if a.startswith("protocols/") else a for a in argv]
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(argv)
        results.append((code, out.getvalue(), err.getvalue()))
    assert [r[0] for r in results] == [0, 0, 0, 0], results
    assert "rig sim-lab (simulated): signed with rig sim-lab's key" in results[2][2]
    assert "1 runs signed, 0 unsigned, 0 bad" in results[3][1]
    assert "rig sim-lab (simulated)" in text
