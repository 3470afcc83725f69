"""Rig configuration files: the shipped example validates, bad ones name the field; hardware opt-in."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rig.core.config import RigConfig
from rig.core.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]


def test_the_example_rig_config_is_valid() -> None:
    cfg = RigConfig.load(ROOT / "protocols" / "examples" / "rig.toml")
    assert cfg.ports.cannon.startswith("/dev/") and cfg.gates.positions_m == (0.75, 0.5, 0.25)
    assert cfg.aim.pressure_for(60.8) == pytest.approx(388.8, abs=1.0)


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("name = 'x'\n", "ports"),
        (
            "[ports]\ncannon='a'\ngates='b'\nclamp='c'\n[gates]\npositions_m=[0.25,0.5,0.75]\n",
            "gates.positions_m",
        ),
        (
            "[ports]\ncannon='a'\ngates='b'\nclamp='c'\n[aim]\npressure_kpa=[1,2]\nspeed_m_s=[3,2]\n",
            "increase",
        ),
        ("[ports\n", "TOML"),
    ],
)
def test_bad_rig_config_names_file_and_field(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as exc:
        RigConfig.load(path)
    assert needle in str(exc.value) and "rig.toml" in str(exc.value)


@pytest.mark.usefixtures("cpu_load")
def test_hardware_tests_run_when_opted_in(tmp_path: Path) -> None:
    """`pytest --hardware RIG.toml` runs tests/hardware; here against a simulated rig's URLs."""
    cfg = tmp_path / "rig.toml"
    cfg.write_text(
        "[ports]\n"
        "cannon = 'sim://cannon?scene=lab&rig=optin'\n"
        "gates = 'sim://gates?scene=lab&rig=optin'\n"
        "clamp = 'sim://clamp?scene=lab&rig=optin'\n"
    )
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "tests/hardware",
            "--hardware",
            str(cfg),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "4 passed" in proc.stdout
