"""A lab's own driver package (examples/lab-driver) plugs in through the `bat_rig.drivers` entry
point, without changing bat-rig: installed into a folder of its own, named by a rig config."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rig.core.tomlfile import dump_toml
from rig.session import sim_config

ROOT = Path(__file__).resolve().parents[2]
BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
PIP_INSTALL = [
    sys.executable,
    "-m",
    "pip",
    "install",
    "--quiet",
    "--no-deps",
    "--no-build-isolation",
    "--no-index",
]


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example package installed (with pip, from its own pyproject) into a folder of its own."""
    work = tmp_path_factory.mktemp("lab-driver")
    shutil.copytree(ROOT / "examples" / "lab-driver", work / "src")
    target = work / "site"
    done = subprocess.run(
        [*PIP_INSTALL, "--target", str(target), str(work / "src")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert list(target.glob("bat_rig_lab_gates-*.dist-info/entry_points.txt"))
    return target


def _config(tmp_path: Path, name: str, **gates: object) -> Path:
    """A rig config file for the simulated lab rig `name`, the gates' table replaced by `gates`."""
    data = json.loads(sim_config("lab", rig_name=name).model_dump_json(exclude_none=True))
    ports = data.pop("ports")
    data["devices"] = {kind: {"address": url} for kind, url in ports.items()}
    data["devices"]["gates"].update(gates)
    path = tmp_path / f"{name}.toml"
    path.write_text(dump_toml(data), encoding="utf-8")
    return path


def _rig(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True, env=env, timeout=600
    )


def _shot(site: Path, config: Path) -> list[dict[str, int]]:
    db = ["--db", str(config.with_suffix(".db"))]  # rig shot records its shot as a run
    done = _rig(site, "shot", "--config", str(config), "--speed", "60", "--json", *db)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout)["crossings"]


def test_the_entry_point_driver_takes_each_screens_delay_off_its_ticks(site: Path, tmp_path: Path) -> None:
    """Two shots in the same simulated world (same noise): with a 1000 ns delay on gate 3 only,
    gate 3's ticks move earlier by exactly 1000 ns and the other gates' stay."""
    plain = _shot(site, _config(tmp_path, "plain", driver="lab-gates"))
    delayed = _shot(
        site, _config(tmp_path, "delayed", driver="lab-gates", options={"delay_ns": [0, 0, 1000.0]})
    )
    assert [c["gate"] for c in plain] == [c["gate"] for c in delayed] and len(plain) >= 5
    shifts = {c["gate"]: p["tick"] - c["tick"] for p, c in zip(plain, delayed, strict=True)}
    assert shifts[1] == shifts[2] == 0
    assert shifts[3] > 0 and shifts[3] * _tick_ns() == pytest.approx(1000.0, abs=_tick_ns())


def _tick_ns() -> float:
    from rig.simulators.scene import Scene

    return Scene.load("lab").rig.tick_ns


def test_a_rig_certifies_through_the_installed_driver_and_verifies(site: Path, tmp_path: Path) -> None:
    config = _config(tmp_path, "certify", driver="lab-gates", options={"delay_ns": [0.0, 0.0, 0.0]})
    db = tmp_path / "lab.db"
    done = _rig(
        site, "certify", "--procedure", "bbcor", "--bat", str(BAT), "--config", str(config), "--db", str(db)
    )
    assert done.returncode in (0, 1), done.stderr[-2000:]
    assert "PASS" in done.stdout or "FAIL" in done.stdout
    verified = _rig(site, "verify", "--db", str(db))
    assert verified.returncode == 0, verified.stdout + verified.stderr


def test_without_the_package_the_name_is_unknown_in_one_line(tmp_path: Path) -> None:
    config = _config(tmp_path, "absent", driver="lab-gates")
    db = ["--db", str(config.with_suffix(".db"))]
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "shot", "--config", str(config), "--speed", "60", *db],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "no driver 'lab-gates'" in lines[0], done.stderr
