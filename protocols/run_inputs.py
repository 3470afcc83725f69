"""What every evaluation of a run shares: the lab air, the input distributions, the drag inputs.

Used by a shot's evaluation (rig.protocols.evaluate) and by the verdict over the hits (rig.protocols.verdict).
"""

from __future__ import annotations

from typing import Any

from rig.core.config import RigConfig
from rig.core.devices import Environment
from rig.measure.drag import AirDensity, lab_air
from rig.measure.model import BALL_DIAMETER_M, Spread, UncertaintyModel
from rig.protocols.procedure import Procedure
from rig.protocols.state import RunState

NOMINAL_AIR = Environment(temperature_c=20.0, humidity_pct=50.0)  # when no check is recorded


def air_density(config: RigConfig, state: RunState) -> AirDensity:
    """The lab air's density from the latest environment check and the rig's stated pressure."""
    env = state.environment or {}
    t = float(env.get("temperature_c", NOMINAL_AIR.temperature_c))
    rh = float(env.get("humidity_pct", NOMINAL_AIR.humidity_pct))
    a = config.air
    return lab_air(t, rh, a.pressure_kpa, a.temperature_u_c, a.humidity_u_pct, a.pressure_u_kpa)


def uncertainty_model(
    p: Procedure,
    config: RigConfig | None = None,
    state: RunState | None = None,
    air: AirDensity | None = None,
) -> UncertaintyModel:
    """The input distributions: the MOI's derived u (its MoiMeasured record), the rig's gates and air."""
    kw: dict[str, Any] = {"coverage_k": p.decision.coverage_k}
    moi = state.moi if state is not None else None
    if moi is not None and moi.u_kgm2 and moi.moi_kgm2:
        kw["moi_relative"] = Spread(width=float(moi.u_kgm2) / float(moi.moi_kgm2))
    if config is not None:
        a = config.air
        kw["gate_position"] = Spread(width=config.gates.position_uncertainty_m, shape="rectangular")
        kw["drag_in"] = Spread(width=a.drag_coefficient_u)
        kw["drag_out"] = Spread(width=a.rebound_drag_coefficient_u)
        air = air or air_density(config, state or RunState())
        kw["air_density"] = Spread(width=air.u)
    return UncertaintyModel(**kw)


def drag_inputs(config: RigConfig | None, air: AirDensity | None) -> tuple[float, float, float, float]:
    """(Cd inbound, Cd rebound, air density, ball diameter) of the drag correction; zeros: none."""
    if config is None or air is None:
        return (0.0, 0.0, 0.0, BALL_DIAMETER_M)
    a = config.air
    return (a.drag_coefficient, a.rebound_drag_coefficient, air.rho, a.ball_diameter_m)
