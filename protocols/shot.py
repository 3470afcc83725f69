"""One shot on the rig: aim, fire, read the gates, compute speeds. Devices come by interface."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from rig.core.config import RigConfig
from rig.core.devices import Cannon, Clamp, FireAware, GateConfig, GateCrossing, Gates, Recoil
from rig.core.errors import DeviceError, DeviceGone, GarbledReply, RigError, SafetyRefusal
from rig.measure.speeds import ShotDataError, shot_speeds, split_passes


class ShotFailed(RigError):
    """The shot produced no usable measurement; the message says why. Raw data is kept."""

    def __init__(self, reason: str, record: ShotRecord | None = None) -> None:
        self.record = record
        super().__init__(reason)


@dataclass(frozen=True)
class ShotRecord:
    """Everything one shot produced: raw gate events first, derived speeds after."""

    shot_number: int
    target_speed_m_s: float
    pressure_kpa: float
    impact_from_pivot_m: float
    gate_positions_m: tuple[float, float, float]
    gate_config: GateConfig
    crossings: tuple[GateCrossing, ...]
    recoil_rad_s: float | None
    inbound_speed_m_s: float | None = None
    rebound_speed_m_s: float | None = None
    pair_speeds_m_s: dict[str, float | None] = field(default_factory=dict)
    extra_crossings: tuple[GateCrossing, ...] = ()
    notes: tuple[str, ...] = ()

    def raw_dict(self) -> dict[str, Any]:
        """The raw part, JSON-ready, as ShotFired records it: nothing derived from the gate events."""
        return {
            "shot_number": self.shot_number,
            "target_speed_m_s": self.target_speed_m_s,
            "pressure_kpa": self.pressure_kpa,
            "impact_from_pivot_m": self.impact_from_pivot_m,
            "gate_positions_m": list(self.gate_positions_m),
            "gate_config": asdict(self.gate_config),
            "crossings": [asdict(c) for c in self.crossings],
            "recoil_rad_s": self.recoil_rad_s,
            "notes": list(self.notes),
        }

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view, raw timestamps included, with the speeds derived from them."""
        out = asdict(self)
        out["gate_config"] = asdict(self.gate_config)
        out["crossings"] = [asdict(c) for c in self.crossings]
        out["extra_crossings"] = [asdict(c) for c in self.extra_crossings]
        return out


def prepare(cannon: Cannon, gates: Gates, clamp: Clamp, impact_from_pivot_m: float) -> GateConfig:
    """Self-test the gates, lock the bat and set the impact point."""
    cfg = gates.config()
    gates.self_test()
    if not clamp.status().locked:
        clamp.clamp()
    clamp.move_to(impact_from_pivot_m * 1000.0)
    return cfg


def fire_shot(
    cannon: Cannon,
    gates: Gates,
    clamp: Clamp,
    config: RigConfig,
    speed_m_s: float,
    gate_config: GateConfig,
    on_crossing: Callable[[GateCrossing], None] | None = None,
) -> ShotRecord:
    """Aim for `speed_m_s`, fire once, collect the gate events and compute speeds.

    `on_crossing` sees each gate event the moment it arrives (live speeds, displays). A clamp that
    is FireAware is told the shot is coming once the tank is ready, before the interlock read (so
    that read stays as close to FIRE as before).
    """
    pressure = config.aim.pressure_for(speed_m_s)
    cannon.set_pressure(pressure, wait_ready=True)
    if isinstance(clamp, FireAware):
        clamp.before_fire()
    status = cannon.status()
    if not status.interlocks.all_closed:
        raise SafetyRefusal("cannon", "interlock open: " + ", ".join(status.interlocks.open_names()))
    gates.arm()
    cannon.arm()
    shot_number = cannon.fire()
    crossings: list[GateCrossing] = []
    notes: list[str] = []
    recoil: Recoil | None = None

    def partial(reason: str) -> ShotFailed:
        return ShotFailed(
            reason, _record(config, speed_m_s, pressure, gate_config, shot_number, crossings, recoil, notes)
        )

    try:
        _collect(gates, config.timeouts.shot_window_s, crossings, notes, on_crossing)
        recoil = clamp.next_recoil(timeout_s=config.timeouts.recoil_s)
    except DeviceGone as exc:
        raise partial(f"device lost mid-shot, raw events so far kept: {exc}") from exc
    finally:
        with contextlib.suppress(DeviceError):
            gates.disarm()
    record = _record(config, speed_m_s, pressure, gate_config, shot_number, crossings, recoil, notes)
    return derive_speeds(record)


def _collect(
    gates: Gates,
    window_s: float,
    crossings: list[GateCrossing],
    notes: list[str],
    on_crossing: Callable[[GateCrossing], None] | None = None,
) -> None:
    """Append gate events until the rebound has passed gate 1 or the line is silent for `window_s`.

    Filled in place, so that what arrived before a failure is kept. A garbled event is noted and
    skipped (its bytes stay in the traffic log); collection goes on.
    """
    started = time.monotonic()
    while time.monotonic() - started < 20 * window_s:
        try:
            for crossing in gates.crossings(timeout_s=window_s):
                crossings.append(crossing)
                if on_crossing is not None:
                    on_crossing(crossing)
                if _shot_complete(crossings):
                    return
            return
        except GarbledReply as exc:
            notes.append(f"skipped a garbled gate event: {exc}")
    notes.append("gate events kept coming; collection stopped at the time limit")


def _record(
    config: RigConfig,
    speed_m_s: float,
    pressure: float,
    gate_config: GateConfig,
    shot_number: int,
    crossings: list[GateCrossing],
    recoil: Recoil | None,
    notes: list[str],
) -> ShotRecord:
    return ShotRecord(
        shot_number=shot_number,
        target_speed_m_s=speed_m_s,
        pressure_kpa=pressure,
        impact_from_pivot_m=config.impact_from_pivot_m,
        gate_positions_m=config.gates.positions_m,
        gate_config=gate_config,
        crossings=tuple(crossings),
        recoil_rad_s=None if recoil is None else recoil.omega_rad_s,
        notes=tuple(notes),
    )


def _shot_complete(crossings: list[GateCrossing]) -> bool:
    """Gate 1 seen again after gate 3: the rebound has left through the last gate."""
    seen_far_gate = any(c.gate == 3 for c in crossings)
    return seen_far_gate and crossings[-1].gate == 1


def derive_speeds(record: ShotRecord) -> ShotRecord:
    """Add the speeds to a record of raw crossings; raise ShotFailed (keeping the record) if none."""
    if not record.crossings:
        raise ShotFailed("no gate events: the ball was not seen (misfire or gates not armed?)", record)
    try:
        passes = split_passes(record.crossings, record.gate_config)
        speeds = shot_speeds(passes, record.gate_positions_m, record.gate_config)
    except ShotDataError as exc:
        raise ShotFailed(str(exc), record) from None
    pairs = {
        "inbound_gates_1_2": speeds.inbound_far,
        "inbound_gates_2_3": speeds.inbound_near,
        "rebound_gates_3_2": speeds.rebound_near,
        "rebound_gates_2_1": speeds.rebound_far,
        "inbound_gates_1_3": speeds.inbound_span,
        "rebound_gates_3_1": speeds.rebound_span,
    }
    derived = ShotRecord(
        **{
            **record.__dict__,
            "inbound_speed_m_s": speeds.inbound,
            "rebound_speed_m_s": speeds.rebound,
            "pair_speeds_m_s": pairs,
            "extra_crossings": passes.extra,
        }
    )
    if speeds.inbound is None:
        raise ShotFailed("inbound speed not measured: fewer than two inbound gates saw the ball", derived)
    if speeds.rebound is None:
        raise ShotFailed("rebound speed not measured: the ball did not come back through two gates", derived)
    return derived
