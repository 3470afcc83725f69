"""A scene: the simulated rig's true geometry, bat, ball and cannon, and the effects it turns on.

Scenes are TOML files; `Scene.load("lab")` reads a built-in from simulators/scenes/, any other
argument is a path. Every field has a default, so a file lists only what differs from the ideal
rig. A refused file raises ConfigError naming the file and the first bad field.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from rig.core.bat import HOOP_HZ, LENGTH_IN, MOI_KGM2, PIVOT_FROM_KNOB_M, WEIGHT_OZ
from rig.core.devices import STAGE_RANGE_MM
from rig.core.errors import ConfigError, ParameterError, shown
from rig.core.files import CONFIG_BYTES, parse_toml, read_text
from rig.core.units import INCH, OUNCE
from rig.physics import CollisionParams
from rig.physics.params import check_physical
from rig.simulators.effects import EffectSpec

SCENES_DIR = Path(__file__).with_name("scenes")
AIM_PRESSURES_KPA = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 800.0)
_FROZEN = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)
Positive = Annotated[float, Field(gt=0.0)]
# A cannon rig is a few metres long: no gate, muzzle or bat sits more than 5 m from the impact point.
RigLength = Annotated[float, Field(gt=0.0, le=5.0)]


class RigGeometry(BaseModel):
    """The rig as built: gate positions, counter, pivot, stage, cannon muzzle."""

    model_config = _FROZEN

    gate_positions_m: tuple[RigLength, ...] = Field(
        (0.75, 0.50, 0.25),
        min_length=2,
        max_length=16,
        description="gate 1, 2, ... distance from the impact point, m (at most 5 m, 2-16 gates)",
    )
    muzzle_m: RigLength = Field(1.5, description="muzzle to impact point, m (at most 5 m)")
    beam_half_height_m: float = Field(
        0.05,
        gt=0.0,
        le=0.5,
        description="a rebounding ball that has dropped more than this passes under the beam (<= 0.5 m)",
    )
    # 1 ns (a 1 GHz counter) to 10 us (100 kHz): coarser cannot time a ball across 20 mm at 80 m/s.
    tick_ns: float = Field(100.0, ge=1.0, le=1e4, description="counter tick, ns (1-10000)")
    counter_bits: int = Field(32, ge=8, le=64)
    counter_start: int = Field(0, ge=0, description="counter value when the world starts")
    pivot_from_knob_m: float = Field(
        PIVOT_FROM_KNOB_M, gt=0.0, le=12 * INCH, description="pivot axis from the knob end, m (<= 12 in)"
    )
    stage_start_mm: float = Field(
        500.0, ge=STAGE_RANGE_MM[0], le=STAGE_RANGE_MM[1], description="stage position at power-up"
    )
    stage_speed_mm_s: float = Field(100.0, ge=1.0, le=2000.0, description="stage travel speed (1-2000)")
    lock_time_s: float = Field(0.3, gt=0.0, le=60.0, description="grip close to lock confirming, s (<= 60)")
    swing_amplitude_deg: float = Field(5.0, gt=0.0, le=30.0, description="SWING release amplitude")

    @model_validator(mode="after")
    def _check(self) -> RigGeometry:
        gates = self.gate_positions_m
        if any(a <= b for a, b in itertools.pairwise(gates)):
            raise ValueError("gate_positions_m must fall strictly from gate 1 (farthest) to the last")
        if self.muzzle_m <= gates[0]:
            raise ValueError(f"muzzle_m {self.muzzle_m} must exceed the farthest gate {gates[0]}")
        if self.counter_start >= 1 << self.counter_bits:
            raise ValueError(f"counter_start must be below 2^{self.counter_bits}")
        return self


class SimBat(BaseModel):
    """The simulated bat's true properties (a 33 in, 30 oz BBCOR-style aluminium bat)."""

    model_config = _FROZEN

    id: str = Field(
        "scene-bat",
        min_length=1,
        max_length=64,
        description="the bat's identity (its bat file's id): seeds its own performance offset",
    )
    # The bounds are a bat file's (rig.core.bat), in SI: 20-42 in, 10-50 oz, 0.01-1 kg m^2, 200-10000 Hz.
    length_m: float = Field(
        33 * INCH, ge=LENGTH_IN[0] * INCH, le=LENGTH_IN[1] * INCH, description="knob end to tip, m"
    )
    mass_kg: float = Field(0.85, ge=WEIGHT_OZ[0] * OUNCE, le=WEIGHT_OZ[1] * OUNCE, description="kg")
    moi_kgm2: float = Field(
        0.19, ge=MOI_KGM2[0], le=MOI_KGM2[1], description="moment of inertia about the pivot, kg m^2"
    )
    balance_point_m: Positive = Field(0.56, description="centre of mass from the knob end, m (on the bat)")
    hoop_hz: float = Field(
        1800.0, ge=HOOP_HZ[0], le=HOOP_HZ[1], description="lowest hoop-mode frequency (trampoline effect)"
    )


class SimBallLot(BaseModel):
    """The lot the simulated balls come from: the scene's `ball` is its nominal new ball at the
    nominal condition (21 C, 50 % RH); each ball differs from it by its own draw of the spread."""

    model_config = _FROZEN

    id: str = Field("SIM-LOT", min_length=1, max_length=32, pattern=r"^[A-Za-z0-9._-]+$")
    c1_spread_rel: float = Field(
        0.0, ge=0.0, le=0.2, description="ball-to-ball standard deviation of the damping c1, relative"
    )
    k1_spread_rel: float = Field(
        0.0, ge=0.0, le=0.2, description="ball-to-ball standard deviation of the stiffness k1, relative"
    )


class Target(BaseModel):
    """What the clamp holds: the bat (default), or a rigid target for ball tests.

    `cylinder` is a rigid solid cylinder of `diameter_m` (the founding paper's CCOR test, ASTM
    F2845's dynamic counterpart); `plate` a rigid flat plate (ASTM F1887's wall). Against either the
    collision is the model's rigid-surface COR (rig.physics.rigid_cor): no recoil, no trampoline,
    no bat MOI. The model has no curvature term, so the diameter is stated, not simulated; on the
    plate the ball's stiffness k1 is scaled by `contact_factor` (1.0: the same contact law as on
    the cylinder, an assumption).
    """

    model_config = _FROZEN

    kind: Literal["bat", "cylinder", "plate"] = Field("bat", description="what the clamp holds")
    # a rod of a few mm is no target; a 0.5 m drum is no cylinder the stage can carry
    diameter_m: float | None = Field(None, ge=0.005, le=0.5, description="cylinder diameter, m")
    contact_factor: float = Field(
        1.0, ge=0.1, le=10.0, description="plate: factor on k1 [assumed 1.0: the same contact law]"
    )

    @model_validator(mode="after")
    def _check(self) -> Target:
        if self.kind == "cylinder" and self.diameter_m is None:
            raise ValueError("a cylinder target needs diameter_m")
        if self.kind != "plate" and self.contact_factor != 1.0:
            raise ValueError("contact_factor belongs to a plate target")
        return self

    @property
    def rigid(self) -> bool:
        """True for a rigid target (no bat in the clamp)."""
        return self.kind != "bat"


class CannonModel(BaseModel):
    """The cannon's physics: muzzle speed v(P) = v_max sqrt(1 - exp(-P/P0)), filling and valves."""

    model_config = _FROZEN

    # Defaults fit the controller's default aim calibration (rig.core.config.AimCalibration) to
    # within 0.6 m/s: 60.8 m/s at about 395 kPa.
    # An air cannon launches a ball at tens of m/s from a tank of a few bar, filled in seconds to
    # minutes; the bounds keep every simulated time finite and within an hour.
    v_max_m_s: float = Field(70.8, ge=10.0, le=100.0, description="muzzle speed at high pressure, m/s")
    p0_kpa: float = Field(295.0, ge=10.0, le=5000.0, description="pressure scale of the curve, kPa")
    fill_rate_kpa_s: float = Field(
        150.0, ge=1.0, le=1e4, description="compressor fill (and regulator) rate, kPa/s (1-10000)"
    )
    settle_s: float = Field(0.5, ge=0.0, le=60.0, description="pressure settling after the fill, s")
    launch_delay_s: float = Field(0.03, ge=0.0, le=1.0, description="FIRE to the ball leaving the muzzle")
    valve_close_s: float = Field(
        0.05, gt=0.0, le=1.0, description="FIRE to the valve closing (FIRED -> SAFE)"
    )

    def muzzle_speed(self, pressure_kpa: float) -> float:
        """Ball speed at the muzzle for a tank pressure, m/s."""
        return self.v_max_m_s * math.sqrt(-math.expm1(-max(pressure_kpa, 0.0) / self.p0_kpa))

    def pressure_for(self, speed: float) -> float:
        """The tank pressure giving `speed` m/s (inverse of muzzle_speed), kPa."""
        ratio = speed / self.v_max_m_s
        if not 0.0 < ratio < 1.0:
            raise ValueError(f"speed {speed} m/s outside the curve's range (0, {self.v_max_m_s})")
        return -self.p0_kpa * math.log1p(-ratio * ratio)


class Scene(BaseModel):
    """Everything the simulated rig is, and which effects are on."""

    model_config = _FROZEN

    name: str = "custom"
    description: str = ""
    seed: int = Field(0, ge=0, lt=2**64)
    rig: RigGeometry = RigGeometry()
    bat: SimBat = SimBat()
    target: Target = Target()
    ball: CollisionParams = CollisionParams()
    lot: SimBallLot = SimBallLot()
    cannon: CannonModel = CannonModel()
    effects: tuple[EffectSpec, ...] = ()
    # the softball class the cannon fires ("44/375": rig.simulators.ball_class), None for the
    # scene's own ball (a baseball); a scene file giving it without a [ball] table fires that class
    ball_class: str | None = Field(None, pattern=r"^\.?[0-9]{2}/[0-9]{3}$")
    # which run of the lab this is, as the host names it (e.g. the store's count of runs): two
    # runs of one scene with another session draw other noise; "" for a scene used on its own
    session: str = ""

    @model_validator(mode="before")
    @classmethod
    def _softball(cls, data: Any) -> Any:
        if not isinstance(data, dict) or not isinstance(data.get("ball_class"), str) or "ball" in data:
            return data
        try:
            return softball_data(data, data["ball_class"], CollisionParams())
        except ConfigError as exc:
            raise ValueError(exc.reason) from None

    @model_validator(mode="after")
    def _check(self) -> Scene:
        bat, rig = self.bat, self.rig
        try:  # the ball of a scene is a real ball (rig.physics.params.PHYSICAL_RANGES)
            check_physical(self.ball)
        except ParameterError as exc:
            raise ValueError(f"ball.{exc.name} {exc.value:g} {exc.reason}") from None
        lever = bat.balance_point_m - rig.pivot_from_knob_m
        if not 0.0 < lever < bat.length_m - rig.pivot_from_knob_m:
            raise ValueError("bat.balance_point_m must lie between the pivot and the tip")
        if bat.moi_kgm2 < bat.mass_kg * lever**2:
            raise ValueError(
                f"bat.moi_kgm2 {bat.moi_kgm2} is below m d^2 = {bat.mass_kg * lever**2:.4f}: "
                "no bat has a negative MOI about its centre of mass"
            )
        filled: dict[str, str] = {}
        for spec in self.active_effects():
            slot = spec.slot
            if slot is not None and slot in filled:
                raise ValueError(f"effects {filled[slot]!r} and {spec.kind!r} both replace the {slot} model")
            if slot is not None:
                filled[slot] = spec.kind
        return self

    def with_bat(self, **true_values: float | str | None) -> Scene:
        """This scene with the bat's true properties replaced, except those the scene file sets.

        Keys are SimBat fields (id, length_m, mass_kg, moi_kgm2, balance_point_m, hoop_hz); a value
        the scene's own [bat] table gives wins, so a scene can override the bat file.
        """
        pinned = self.bat.model_fields_set
        update = {k: v for k, v in true_values.items() if v is not None and k not in pinned}
        try:
            bat = SimBat.model_validate({**self.bat.model_dump(), **update})
            return self.model_validate({**self.model_dump(), "bat": bat.model_dump()})
        except ValidationError as exc:
            error = _config_error("", exc)
            where = f"simulated rig {self.name!r} with this bat"
            raise ConfigError(error.reason, source=where, field=error.field) from None

    def with_target(self, kind: str, diameter_m: float | None = None) -> Scene:
        """This scene with the clamp holding `kind` (bat, cylinder, plate), as the lab says.

        A value the scene's own [target] table gives wins (its contact factor always does).
        """
        pinned = self.target.model_fields_set
        update: dict[str, Any] = {"kind": kind, "diameter_m": diameter_m}
        update = {k: v for k, v in update.items() if k not in pinned}
        try:
            target = Target.model_validate({**self.target.model_dump(), **update})
            return self.model_validate({**self.model_dump(exclude_unset=True), "target": target.model_dump()})
        except ValidationError as exc:
            error = _config_error("", exc)
            where = f"simulated rig {self.name!r} with this target"
            raise ConfigError(error.reason, source=where, field=error.field) from None

    def with_ball_class(self, key: str | None) -> Scene:
        """This scene firing softballs of class `key` (rig.simulators.ball_class), as a lab loads the
        balls its procedure names: the scene's ball law with the class's mass, stiffness and COR,
        the drag effect's diameter the class's. None (or the class it fires already): unchanged."""
        if key is None or key.lstrip(".") == (self.ball_class or "").lstrip("."):
            return self
        data = softball_data(self.model_dump(exclude_unset=True), key, self.ball)
        try:
            return self.model_validate(data)
        except ValidationError as exc:
            raise _config_error(f"simulated rig {self.name!r} with {key} softballs", exc) from None

    def with_alteration(self, bbcor: float) -> Scene:
        """This scene with its bat altered: `bbcor` more BBCOR (trampoline effect's alteration_bbcor)."""
        if not any(e.kind == "trampoline" for e in self.effects):
            raise ConfigError("the scene has no trampoline effect: a bat cannot be altered", self.name)
        return self.with_effect("trampoline", alteration_bbcor=bbcor)

    def with_effect(self, kind: str, **values: float) -> Scene:
        """This scene with fields of its `kind` effect replaced (the bat keeps what it was given).

        The scene is rebuilt from the fields that were set, so that a later `with_bat` still
        replaces the bat's properties the scene's own [bat] table does not give.
        """
        effects = [{**e.model_dump(), **values} if e.kind == kind else e.model_dump() for e in self.effects]
        if not any(e["kind"] == kind for e in effects):
            raise ConfigError(f"the scene has no {kind} effect", self.name)
        try:
            return self.model_validate({**self.model_dump(exclude_unset=True), "effects": effects})
        except ValidationError as exc:
            raise _config_error(f"simulated rig {self.name!r}, {kind}", exc) from None

    def run_key(self) -> str:
        """What tells one run in the simulated lab from another: the seed, what the clamp holds (the
        bat's id, or the target), when (the environment's start in its swing of air) and the
        session the host names (`session`: the CLI gives each run its own).

        The effects' random streams are keyed by it: a run of one scene in one session repeats
        exactly, while two bats, a ball test at two hours, or a test run again draw their own
        noise (as on a real rig).
        """
        held = self.bat.id if self.target.kind == "bat" else f"{self.target.kind}-{self.target.diameter_m}"
        air = [e for e in self.active_effects() if e.kind == "environment"]
        start = float(getattr(air[0], "start_s", 0.0)) if air else 0.0
        return f"{self.seed}/{held}/{start!r}/{self.session}"

    def active_effects(self) -> list[Any]:
        """The effect configurations that are enabled, in scene order."""
        return [e for e in self.effects if e.enabled]

    def rig_config_fragment(self, pressures_kpa: tuple[float, ...] = AIM_PRESSURES_KPA) -> dict[str, Any]:
        """The part of the controller's rig config this scene fixes: gate positions and aim table.

        Shaped like rig.core.config.RigConfig (`gates.positions_m`, `aim.pressure_kpa/speed_m_s`);
        the counter's tick and width come over the wire (gates CFG).
        """
        speeds = tuple(round(self.cannon.muzzle_speed(p), 3) for p in pressures_kpa)
        return {
            "gates": {"positions_m": tuple(self.rig.gate_positions_m)},
            "aim": {"pressure_kpa": tuple(pressures_kpa), "speed_m_s": speeds},
            "air": self._air_fragment(),
        }

    def reports_recoil(self) -> bool:
        """Whether the simulated clamp reports a recoil after each impact (the recoil effect, on a bat)."""
        return not self.target.rigid and any(e.slot == "recoil" for e in self.active_effects())

    def _air_fragment(self) -> dict[str, float]:
        """The ball's Cd as a lab that measured it would state it: the drag effect's, else none."""
        drag = next((e for e in self.active_effects() if e.kind == "drag"), None)
        if drag is None:  # straight-line flight: the rig has no drag to correct
            return {k: 0.0 for k in ("drag_coefficient", "drag_coefficient_u")} | {
                "rebound_drag_coefficient": 0.0,
                "rebound_drag_coefficient_u": 0.0,
            }
        cd = drag.drag_coefficient
        return {
            "drag_coefficient": cd,
            "rebound_drag_coefficient": cd,
            "ball_diameter_m": drag.ball_diameter_m,
        }

    @classmethod
    def builtin_names(cls) -> list[str]:
        """Names of the scenes shipped in simulators/scenes/."""
        return sorted(p.stem for p in SCENES_DIR.glob("*.toml"))

    @classmethod
    def load(cls, name_or_path: str | Path) -> Scene:
        """A built-in scene by name, or a scene file by path; ConfigError if refused."""
        path = Path(name_or_path)
        if str(name_or_path) in cls.builtin_names():
            path = SCENES_DIR / f"{name_or_path}.toml"
        known = ", ".join(cls.builtin_names())
        text = read_text(
            path, CONFIG_BYTES, "a scene file", missing=f"no such scene file; built-in scenes: {known}"
        )
        return cls.from_toml(text, source=str(path), default_name=path.stem)

    @classmethod
    def from_toml(cls, text: str, source: str = "<scene>", default_name: str = "custom") -> Scene:
        """Parse and validate scene TOML; `source` names the file in errors."""
        data = parse_toml(text, source, "a scene file")
        data.setdefault("name", default_name)
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise _config_error(source, exc) from None


def softball_data(data: dict[str, Any], key: str, base: CollisionParams) -> dict[str, Any]:
    """Scene data firing class `key`: its ball from `base` (rig.simulators.ball_class), its class
    recorded, each drag effect's ball diameter the class's; ConfigError for an unknown class."""
    from rig.simulators.ball_class import ball_class  # scipy's root finder: only for softballs

    chosen = ball_class(key)
    effects = [
        {**e, "ball_diameter_m": chosen.diameter_m} if isinstance(e, dict) and e.get("kind") == "drag" else e
        for e in (data.get("effects") or ())
    ]
    out = {**data, "ball_class": chosen.key, "ball": chosen.params(base).model_dump()}
    return out | ({"effects": effects} if "effects" in data else {})


def _config_error(source: str, exc: ValidationError) -> ConfigError:
    errors = exc.errors()
    first = errors[0]
    field = ".".join(str(p) for p in first["loc"]) or "(scene)"
    reason = first["msg"]
    if first["loc"] and "input" in first and not isinstance(first["input"], dict):
        reason += f" (got {shown(first['input'])})"
    if len(errors) > 1:
        reason += f"; and {len(errors) - 1} more error(s)"
    return ConfigError(reason, source, field)
