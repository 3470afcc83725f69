"""Composition root: a rig config becomes open devices; the CLI and the UI drive a session.

Simulation is chosen by the port URLs alone (`sim://...`): the same drivers run either way.
This is the one place that knows both the drivers and the simulators exist; which driver runs a
device is the rig config's choice (rig.drivers.registry).
"""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from urllib.parse import quote

from rig.core.bat import BatSpec
from rig.core.config import DEVICE_KINDS, OPTIONAL_KINDS, RigConfig
from rig.core.errors import ConfigError
from rig.core.units import INCH
from rig.drivers.registry import DriverContext, open_device
from rig.drivers.traffic import TrafficRecord

if TYPE_CHECKING:
    from rig.simulators.scene import Scene


# A lab that tests balls (60 mph, 25 m/s) calibrates its cannon's aim down to low pressures too.
BALL_AIM_PRESSURES_KPA = (20.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 150.0, 200.0, 300.0, 400.0, 500.0, 600.0)


def air_starting_at(start_s: float) -> dict[str, dict[str, Any]]:
    """Effect overrides for `sim_config`: the scene's air starts `start_s` virtual s into its swing
    (not at the point the seed and the bat draw): the hour a simulated ball test is run at."""
    return {"environment": {"start_s": start_s, "random_start": False}}


def sim_config(
    scene: str = "ideal",
    rig_name: str | None = None,
    bat: BatSpec | None = None,
    target: tuple[str, float | None] | None = None,
    effects: Mapping[str, Mapping[str, Any]] | None = None,
    session: str | None = None,
    ball_class: str | None = None,
    speed_m_s: float | None = None,
    balls_of: str | None = None,
) -> RigConfig:
    """A rig config whose ports are simulated devices of `scene` (a built-in name or a TOML path).

    The gate positions and the aim table come from the scene, as a lab would measure them on
    its own rig; the equipment register is a sample in date (rig.simulators.register); everything
    else is the controller's default. With `bat`, the simulated bat takes
    the bat file's properties as its true ones, unless the scene's [bat] table sets them. With
    `target` (kind, diameter in m), the simulated clamp holds the rigid cylinder or plate a ball
    test names, as the lab clamps it (the scene's own [target] table wins), and the aim table
    reaches down to ball-test speeds. `effects` replaces fields of the scene's effects by kind (e.g.
    `air_starting_at(900.0)`: the hour a ball test is run at). `session` names this run of the
    simulated lab (Scene.run_key): another session draws other noise, the same one repeats it.
    `ball_class` (a procedure's "44/375"): the cannon fires softballs of that class, as the lab loads
    the balls its procedure names (Scene.with_ball_class). `speed_m_s`: the speed the run fires at;
    below the default aim table's reach (a BPF's 60 mph), the aim table reaches down as a ball test's.
    `balls_of`: the procedure whose balls `ball_class` is (None for baseballs); with it, a scene
    that loads baseballs refuses a softball class and a softball scene refuses baseballs
    (refuse_other_balls): the lab loads other balls, it does not change its rig.
    """
    from rig.instruments import today_utc
    from rig.simulators.register import sample_register
    from rig.simulators.scene import Scene
    from rig.simulators.urlhandler import install_world, register

    register()
    loaded = Scene.load(scene)
    rig = rig_name or f"session-{uuid.uuid4().hex[:8]}"
    if bat is not None:
        loaded = scene_with_bat(loaded, bat)
    if target is not None:
        loaded = loaded.with_target(*target)
    if balls_of is not None:
        refuse_other_balls(loaded, scene, ball_class, balls_of)
    softball = loaded.with_ball_class(ball_class)
    changed = softball is not loaded
    loaded = softball
    for kind, values in (effects or {}).items():
        loaded = loaded.with_effect(kind, **values)
    if session:
        loaded = loaded.model_copy(update={"session": session})
    if bat is not None or target is not None or effects or session or changed:
        install_world(rig, scene, loaded)
    ports = {dev: f"sim://{dev}?scene={quote(scene, safe='')}&rig={rig}" for dev in DEVICE_KINDS}
    low = target is not None or (speed_m_s is not None and speed_m_s < loaded.cannon.muzzle_speed(150.0))
    fragment = loaded.rig_config_fragment(BALL_AIM_PRESSURES_KPA) if low else loaded.rig_config_fragment()
    balls = f", softballs {loaded.ball_class}" if loaded.ball_class else ""
    data = {
        "name": f"simulated rig ({loaded.name}{balls})",
        "ports": ports,
        **fragment,
        "equipment": sample_register(today_utc()),  # a sample register, one item per role, in date
    }
    if not loaded.reports_recoil():  # as a lab states a clamp without an encoder: no recoil waited for
        data["devices"] = {"clamp": {"options": {"recoil_encoder": False}}}
    return RigConfig.from_dict(data, source=f"scene {scene}")


def refuse_other_balls(loaded: Any, scene: str, ball_class: str | None, balls_of: str) -> None:
    """ConfigError (one line) if the simulated rig `loaded` (scene `scene`) loads softballs and the
    procedure `balls_of` fires baseballs (no `ball_class`), or the other way round; another class of
    softball is loaded as the procedure names it (Scene.with_ball_class)."""
    from rig.simulators.scene import Scene

    if (ball_class is None) == (loaded.ball_class is None):
        return
    fitting = [n for n in Scene.builtin_names() if (Scene.load(n).ball_class is None) == (ball_class is None)]
    theirs = f"softballs {loaded.ball_class}" if loaded.ball_class else "baseballs (no ball class)"
    ours = f"softballs of class {ball_class}" if ball_class else "baseballs (no ball class)"
    raise ConfigError(
        f"{balls_of} fires {ours}; the simulated rig {scene!r} loads {theirs}: give "
        + " or ".join(f"--sim {n}" for n in fitting),
        source="--sim",
    )


def scene_with_bat(scene: Scene, bat: BatSpec) -> Scene:
    """`scene` whose simulated bat has the bat file's properties, except those the scene's [bat] sets.

    The file's [simulated] table (true MOI, true hoop frequency, an alteration) wins over its [bat]
    table: it is what the simulated bat really is, and the controller never reads it.
    """
    truth = bat.simulated
    out = scene.with_bat(
        id=bat.id,
        length_m=bat.length_m,
        mass_kg=bat.mass_kg,
        moi_kgm2=truth.moi_kgm2 if truth is not None and truth.moi_kgm2 is not None else bat.moi_kgm2,
        balance_point_m=None if bat.balance_point_in is None else bat.balance_point_in * INCH,
        hoop_hz=truth.hoop_hz if truth is not None and truth.hoop_hz is not None else bat.hoop_hz,
    )
    if truth is not None and truth.alteration_bbcor > 0.0:
        out = out.with_alteration(truth.alteration_bbcor)
    return out


@dataclass
class RigSession:
    """The open devices of one rig and the raw traffic they have exchanged.

    Each device is made by the driver its rig config names (rig.drivers.registry): the rig's own
    line protocol, an instrument class, or a lab's own package.
    """

    config: RigConfig
    cannon: Any  # rig.core.devices.Cannon (+ BallLoader when the driver can name balls), closable
    gates: Any  # rig.core.devices.Gates, closable
    clamp: Any  # rig.core.devices.Clamp, closable
    traffic: list[tuple[str, TrafficRecord]] = field(default_factory=list)
    closed: bool = field(default=False, init=False)
    compression: Any = None  # rig.core.devices.CompressionTester, closable; None: the rig has none

    @classmethod
    def open(cls, config: RigConfig, source: str = "rig config") -> RigSession:
        """Open every device named in the config; a failure closes what was opened and re-raises."""
        if any(address.startswith("sim://") for address in config.addresses().values()):
            from rig.simulators.urlhandler import register

            register()
        traffic: list[tuple[str, TrafficRecord]] = []
        opened: list[Any] = []

        def log(name: str) -> Callable[[TrafficRecord], None]:
            return lambda rec: traffic.append((name, rec))

        kinds = [*DEVICE_KINDS, *(k for k in OPTIONAL_KINDS if getattr(config.devices, k) is not None)]
        try:
            for kind in kinds:
                spec = config.device(kind)
                context = DriverContext(
                    kind=kind,
                    name=kind,
                    address=str(spec.address),
                    options=spec.options,
                    timeouts=config.timeouts,
                    on_traffic=log(kind),
                    source=source,
                    gate_positions_m=config.gates.positions_m,
                )
                opened.append(open_device(kind, context, spec))
        except BaseException:
            for dev in opened:
                with contextlib.suppress(Exception):
                    dev.close()
            raise
        cannon, gates, clamp, *optional = opened
        session = cls(config, cannon, gates, clamp, traffic)
        for kind, device in zip(kinds[len(DEVICE_KINDS) :], optional, strict=True):
            setattr(session, kind, device)
        return session

    def close(self) -> None:
        """Leave the cannon safe (vent), then close every port; a second call does nothing."""
        if self.closed:
            return
        self.closed = True
        # Closing must go on even when the cannon's port is already gone.
        with contextlib.suppress(Exception):
            self.cannon.vent()
        for dev in (self.cannon, self.gates, self.clamp, self.compression):
            if dev is not None:
                dev.close()

    def __enter__(self) -> RigSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
