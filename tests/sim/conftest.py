"""Fixtures for the simulator tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from rig.simulators.scene import Scene
from rig.simulators.urlhandler import register, reset_worlds
from rig.simulators.world import SimWorld
from tests.sim.hosts import Rig


@pytest.fixture
def ideal() -> Scene:
    return Scene.load("ideal")


@pytest.fixture
def rig(ideal: Scene) -> Rig:
    return Rig(SimWorld(ideal))


@pytest.fixture
def sim_ports() -> Iterator[None]:
    """sim:// registered, with no world left over from another test."""
    register()
    reset_worlds()
    yield
    reset_worlds()
