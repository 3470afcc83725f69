"""The package metadata that `make install` builds from: nothing setuptools warns about."""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

from packaging.licenses import canonicalize_license_expression
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[2]


def test_the_license_is_an_spdx_expression_that_the_required_setuptools_reads() -> None:
    """A license table is deprecated (setuptools printed the warning three times per install); the
    SPDX string form needs setuptools 77 or newer in the build."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    license_ = data["project"]["license"]
    assert isinstance(license_, str), license_
    assert canonicalize_license_expression(license_) == license_
    (setuptools,) = [Requirement(r) for r in data["build-system"]["requires"] if r.startswith("setuptools")]
    floor = [s.version for s in setuptools.specifier if s.operator == ">="]
    assert floor and int(floor[0].split(".")[0]) >= 77, setuptools


# -- one import name: the folders drivers/, protocols/, simulators/ install as rig.drivers etc.

BARE = ("drivers", "protocols", "simulators")
DOTTED = re.compile(r"(drivers|protocols|simulators)(\.\w+)+")
SKIP = {".venv", ".git", "build", "dist", "out", "__pycache__", ".mypy_cache", ".ruff_cache", ".pytest_cache"}


def _sources() -> list[Path]:
    """Every Python file of the repository once (the links rig/drivers etc. are not walked twice)."""
    found: list[Path] = []
    for folder, dirs, files in os.walk(ROOT):  # the skipped folders (.venv: ~10 s) are not entered
        here = Path(folder)
        rel = here.relative_to(ROOT).parts
        dirs[:] = [
            d for d in dirs if d not in SKIP and d != ".hypothesis" and not (rel == ("rig",) and d in BARE)
        ]
        found += [here / name for name in files if name.endswith(".py")]
    return sorted(found)


def _bare_imports(path: Path) -> list[str]:
    """`import drivers...`, `from protocols... import`, and strings that name a bare module."""
    text = path.read_text(encoding="utf-8")
    if not any(name in text for name in BARE):  # every hit names one: a file without them has none
        return []
    tree = ast.parse(text, filename=str(path))
    hits: list[str] = []
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            names = [node.value] if DOTTED.fullmatch(node.value) else []
        where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', '?')}"
        hits += [f"{where}: {name}" for name in names if name.split(".")[0] in BARE]
    return hits


def test_nothing_imports_the_folders_under_their_bare_names() -> None:
    """From the repository's root `import drivers` would still work, and would load a second copy of
    every driver class beside rig.drivers' (isinstance then fails): every import names rig.*."""
    sources = _sources()
    assert len(sources) > 300 and any(p.parts[-2] == "drivers" for p in sources), len(sources)
    hits = [hit for path in sources for hit in _bare_imports(path)]
    assert not hits, "\n".join(hits)


def _wheel(tmp_path: Path) -> Path:
    """Build the project's wheel from a copy of the tree (the build writes beside its sources)."""
    tree = tmp_path / "tree"
    shutil.copytree(
        ROOT, tree, symlinks=True, ignore=shutil.ignore_patterns(*SKIP, ".hypothesis", "*.egg-info")
    )
    dist = tmp_path / "dist"
    code = "import sys; from setuptools import build_meta as b; print(b.build_wheel(sys.argv[1]))"
    done = subprocess.run(
        [sys.executable, "-c", code, str(dist)], cwd=tree, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return dist / done.stdout.strip().splitlines()[-1]


def test_the_wheel_installs_rig_and_studies_and_their_data(tmp_path: Path) -> None:
    """Installed from the wheel, the project adds `rig` and its studies (`studies`, the rig-study
    command) to the environment and nothing else: the generic names drivers and simulators are
    other projects' on the package index."""
    wheel = _wheel(tmp_path)
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        top = {name.split("/")[0] for name in names}
        (info,) = [t for t in top if t.endswith(".dist-info")]
        assert top == {"rig", "studies", info}, sorted(top)
        assert archive.read(f"{info}/top_level.txt").decode().split() == ["rig", "studies"]
        scripts = archive.read(f"{info}/entry_points.txt").decode()
        assert "rig = rig.cli:main" in scripts and "rig-study = studies.cli:main" in scripts, scripts
        for needed in (
            "rig/drivers/transport.py",
            "rig/drivers/cannon/codec.py",
            "rig/protocols/runner.py",
            "rig/protocols/examples/sample-bat.toml",
            "rig/simulators/urlhandler/protocol_sim.py",
            "rig/simulators/scenes/lab.toml",
            "rig/__init__.pyi",
            "studies/cli/__init__.py",
        ):
            assert needed in names, needed
        archive.extractall(tmp_path / "site")
    probe = (
        "import importlib.util, rig.drivers.transport\n"
        "import rig.simulators.scene as s, rig.protocols.procedure as p\n"
        "print(rig.__file__); print(rig.drivers.transport.__file__)\n"
        "print((s.SCENES_DIR / 'lab.toml').is_file(), (p.BUILTIN_DIR / 'bbcor.toml').is_file())\n"
        "print([n for n in ('drivers', 'protocols', 'simulators') if importlib.util.find_spec(n)])\n"
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    rig_file, transport_file, data, bare = done.stdout.splitlines()
    assert rig_file.startswith(str(tmp_path / "site")) and transport_file.startswith(str(tmp_path / "site"))
    assert data == "True True"
    assert bare == "[]"


def test_the_development_install_exposes_rig_and_studies_only(tmp_path: Path) -> None:
    """`make install` (an editable install) maps `rig` and `studies` to the repository and nothing
    else; outside the repository's root the bare folder names do not import."""
    probe = (
        "import importlib.util, rig.drivers, studies.cli\n"
        "print([n for n in ('drivers', 'protocols', 'simulators') if importlib.util.find_spec(n)])\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"
