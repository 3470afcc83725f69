"""The worlds of the sim:// handler: one SimWorld per rig name, shared by its devices."""

from __future__ import annotations

import threading

from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld

DEFAULT_RIG = "default"
DEFAULT_SCENE = "ideal"

_lock = threading.Lock()


class RigConflict(RuntimeError):
    """A sim:// open that contradicts what is running (another scene, a port already open)."""


_worlds: dict[str, tuple[str, SimWorld]] = {}
_open: set[tuple[str, str]] = set()


def world_for(rig: str, scene: str) -> SimWorld:
    """The world of rig `rig`, built from `scene` the first time; refuses a different scene."""
    with _lock:
        known = _worlds.get(rig)
        if known is None:
            known = (scene, SimWorld(Scene.load(scene)))
            _worlds[rig] = known
        elif known[0] != scene:
            raise RigConflict(f"sim rig {rig!r} already runs scene {known[0]!r}, not {scene!r}")
        return known[1]


def install_world(rig: str, scene_ref: str, scene: Scene) -> SimWorld:
    """Build rig `rig`'s world from a prepared Scene (e.g. with the bat under test), before any open.

    Later opens must name the same `scene_ref`; installing over a running rig is refused.
    """
    with _lock:
        if rig in _worlds:
            raise RigConflict(f"sim rig {rig!r} is already running")
        world = SimWorld(scene)
        _worlds[rig] = (scene_ref, world)
        return world


def get_world(rig: str = DEFAULT_RIG) -> SimWorld:
    """The running world of rig `rig` (for tests: open the door, inspect the true shots)."""
    with _lock:
        if rig not in _worlds:
            raise KeyError(f"no sim rig {rig!r} is running; open a sim:// port first")
        return _worlds[rig][1]


def claim(rig: str, device: str) -> None:
    """Mark a device's port open; a second open of the same port is refused, as on hardware."""
    with _lock:
        if (rig, device) in _open:
            raise RigConflict(f"sim://{device} of rig {rig!r} is already open")
        _open.add((rig, device))


def release(rig: str, device: str) -> None:
    """Mark a device's port closed."""
    with _lock:
        _open.discard((rig, device))


def drop_world(rig: str) -> None:
    """Forget rig `rig`'s world once its ports are closed (a population run builds one per bat)."""
    with _lock:
        if any(r == rig for r, _ in _open):
            raise RigConflict(f"sim rig {rig!r} still has open ports")
        _worlds.pop(rig, None)


def reset_worlds() -> None:
    """Forget every world (for tests): the next open builds a fresh one."""
    with _lock:
        _worlds.clear()
        _open.clear()
