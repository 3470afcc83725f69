"""Shared recordings for the modal tests: simulated once per session, written to files where needed."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.modal import ModalResult, Recording, SimSettings, analyze, bat_modes, simulate, write_csv

HOOP_HZ = 2100.0
BENDING_HZ = 175.0


@pytest.fixture(scope="session")
def settings() -> SimSettings:
    """Five hits, 0.2 s apart, light noise: a good recording."""
    return SimSettings(hits=5, hit_interval_s=0.2, noise=1e-3, seed=3, modes=bat_modes(HOOP_HZ, BENDING_HZ))


@pytest.fixture(scope="session")
def recording(settings: SimSettings) -> Recording:
    return simulate(settings)


@pytest.fixture(scope="session")
def result(recording: Recording) -> ModalResult:
    return analyze(recording)


@pytest.fixture(scope="session")
def csv_file(recording: Recording, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_csv(recording, tmp_path_factory.mktemp("modal") / "good.csv", ["a good simulated recording"])
