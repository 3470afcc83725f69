"""The simulated break-in bench: the barrel-compression tester's twin on a simulated rig's world, and
the hands that roll that world's barrel as a run's rollings say and tap it after.

`rig certify --procedure abi --sim composite` runs the tester's twin (rig.simulators.instruments.
compression_tester) on a port of 127.0.0.1 for the run, through the real driver, and rolls the
simulated barrel as each rolling is reported; then it taps the barrel (a ping synthesized at the
world's hoop frequency, rig.simulators.tap) and finds the hoop frequency with its u by the tap
analysis (rig.modal.tap), as an operator with a phone would. A resumed run rolls the new world's barrel by the
rollings its record holds first, so that its stages squeeze and shoot the barrel they left.
"""

from __future__ import annotations

from collections.abc import Sequence
from urllib.parse import parse_qs, urlsplit

from rig.core.config import DeviceSpec, RigConfig
from rig.core.errors import ConfigError
from rig.modal.tap import analyze_tap
from rig.modal.wav import Wav
from rig.simulators import tap
from rig.simulators.instruments.compression_tester import CompressionTesterTwin
from rig.simulators.urlhandler import get_world
from rig.simulators.urlhandler.registry import world_for
from rig.simulators.world import SimWorld


def world_of(config: RigConfig) -> SimWorld:
    """The world a simulated rig config's sim:// ports open (ConfigError for another rig)."""
    address = config.addresses()["cannon"]
    if not address.startswith("sim://"):
        raise ConfigError("the simulated break-in bench needs a --sim rig", source="--sim")
    query = parse_qs(urlsplit(address).query)
    rig, scene = query["rig"][0], query["scene"][0]
    try:
        return get_world(rig)
    except KeyError:
        return world_for(rig, scene)


class SimBreakIn:
    """The tester's twin and the barrel's rolling, for one simulated run; `rolled`: the rollings a
    resumed run has recorded (depth in, passes), rolled into the world before it goes on."""

    def __init__(self, rolled: Sequence[tuple[float, int]] = ()) -> None:
        self.rolled = list(rolled)
        self.world: SimWorld | None = None
        self.twin: CompressionTesterTwin | None = None

    def attach(self, config: RigConfig) -> RigConfig:
        """`config` with the twin as its [devices.compression] (started the first time, the recorded
        rollings rolled then); a scene whose barrel does not soften is refused in one line."""
        if self.twin is None:
            world = world_of(config)
            if world.barrel is None:
                raise ConfigError(
                    "the accelerated break-in rolls a barrel that softens: use --sim composite "
                    "(or a scene with a barrel_softening effect)",
                    source="--sim",
                )
            for depth_in, passes in self.rolled:
                world.roll(depth_in, passes)
            twin = CompressionTesterTwin(world)
            twin.start()
            self.world, self.twin = world, twin
        devices = config.devices.model_copy(update={"compression": DeviceSpec(**self.twin.device_table())})
        return config.model_copy(update={"devices": devices})

    def roll(self, depth_in: float, passes: int) -> tuple[float, float]:
        """Roll the simulated barrel as reported, tap it: its hoop frequency and u found, Hz."""
        if self.world is None:
            raise RuntimeError("the bench has no world yet: attach it to the run's rig config first")
        hoop = self.world.roll(depth_in, passes)
        self.rolled.append((depth_in, passes))
        samples = tap.ping(hoop, seed=len(self.rolled))[:, None]
        found = analyze_tap(Wav(samples, float(tap.RATE_HZ), 16, False, "simulated tap")).hoop
        return found.frequency_hz, found.u_hz

    def close(self) -> None:
        """Stop the twin."""
        if self.twin is not None:
            self.twin.close()
