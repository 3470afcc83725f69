"""A simulated rig loads the balls of its scene: a procedure firing softballs on a baseball scene (or
baseballs on a softball scene) is refused before anything fires, in one line, also by the dry run;
--sim's help names every built-in scene, as the scenes folder holds them."""

from __future__ import annotations

import contextlib
import io
import sqlite3
from contextlib import closing
from pathlib import Path

import pytest

from rig.cli import main
from rig.simulators.scene import Scene
from tests.unit.clirun import run_cli

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "protocols" / "examples"


def _shots(db: Path) -> int:
    if not db.exists():
        return 0
    with closing(sqlite3.connect(db)) as conn:
        return conn.execute("SELECT count(*) FROM log").fetchone()[0]


@pytest.mark.parametrize("dry", [False, True])
def test_softballs_on_a_baseball_scene_are_refused_before_firing(tmp_path: Path, dry: bool) -> None:
    db = tmp_path / "m.db"
    argv = ["certify", "--procedure", "softball-bbs", "--bat", str(EXAMPLES / "softball-bat.toml")]
    result = run_cli([*argv, "--sim", "lab", "--db", str(db), *(["--dry-run"] if dry else [])])
    assert result.code == 2 and result.err.count("\n") == 1, result.err
    assert "44/375" in result.err and "'lab' loads baseballs" in result.err and "--sim softball" in result.err
    assert _shots(db) == 0


def test_baseballs_on_a_softball_scene_are_refused_before_firing(tmp_path: Path) -> None:
    lot = tmp_path / "lot.toml"
    lot.write_text('[lot]\nid = "B1"\nmaker = "Acme"\nmodel = "M"\n', encoding="utf-8")
    db = tmp_path / "b.db"
    assert run_cli(["balls", "register", str(lot), "--db", str(db)]).code == 0
    before = _shots(db)
    result = run_cli(
        ["balls", "test", "--procedure", "ball-cor", "--lot", "B1", "--sim", "softball", "--db", str(db)]
    )
    assert result.code == 2 and result.err.count("\n") == 1, result.err
    assert "'softball' loads softballs 44/375" in result.err and "--sim lab" in result.err
    assert _shots(db) == before


def test_the_sim_help_names_every_built_in_scene() -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        main(["certify", "--help"])
    text = " ".join(out.getvalue().split())
    names = Scene.builtin_names()
    assert "softball" in names and "composite" in names
    assert f"a built-in scene ({', '.join(names)};" in text


def test_rig_help_lists_the_built_in_procedures_and_ball_tests() -> None:
    from rig.measure.registry import BUILTIN_PROCEDURES
    from rig.protocols.names import BALL_BUILTIN

    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(out.getvalue().split())
    assert f"certify a bat ({', '.join(n for _, n in BUILTIN_PROCEDURES)}, abi)" in text
    assert f"ball tests ({', '.join(BALL_BUILTIN)})" in text
    assert "fastpitch-bpf" in text and "ball-cor-fastpitch" in text
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    procedures = readme.split("- **Procedure**", 1)[1].split("\n- **", 1)[0]
    for _, name in BUILTIN_PROCEDURES:
        assert f"`{name}`" in procedures
    for name in BALL_BUILTIN:
        assert f"`{name}`" in procedures
    assert "--procedure abi" in procedures
