"""Many pivoted bats under one set of constants: the kernel's lanes built as arrays, not Impacts.

A calibration solves every bat of a population once per model evaluation; building an Impact
(and its checks) per bat cost about a third of each evaluation at 1,000 bats. Here the lanes of
one constant set are one row of kernel parameters tiled, with each bat's barrel spring
k2 = m2 (2 pi f)^2, body 1/(I/Q^2 - m2) and base 1/(I/Q^2) filled in as columns, as
`curve.cor_grid` does for the clamped barrel. The numbers are those of `solve_batch` over
`impact_for` (tests/physics/test_bat_batch.py holds them equal).
"""

from __future__ import annotations

import math

import numpy as np

from rig.core.errors import ParameterError
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams, check_speed, check_tolerance
from rig.physics.reference import contact_time_limit


class _LazyImpacts:
    """The Impact of lane k, built only when an error message needs it."""

    def __init__(self, params: CollisionParams, speed: float, hoops: np.ndarray, body: np.ndarray) -> None:
        self._args = (params, speed, hoops, body)

    def __getitem__(self, k: int) -> Impact:
        params, speed, hoops, body = self._args
        return Impact(params, speed, float(hoops[k]), body_mass=float(body[k]))


def pivoted_cor_batch(
    params: CollisionParams,
    speed: float,
    hoop_hz: np.ndarray,
    effective_mass: np.ndarray,
    rtol: float = fast.DEFAULT_RTOL,
) -> tuple[np.ndarray, np.ndarray]:
    """e_A and contact time of the ball on each pivoted bat (hoop frequency, I/Q^2) in parallel lanes."""
    speed = check_speed(speed)
    rtol = check_tolerance(rtol)
    hoops = np.asarray(hoop_hz, dtype=float)
    eff = np.asarray(effective_mass, dtype=float)
    if hoops.size and not (np.all(np.isfinite(hoops)) and np.all(hoops > 0)):
        bad = hoops[~(np.isfinite(hoops) & (hoops > 0))][0]
        raise ParameterError("hoop_hz", float(bad), "must be finite and > 0 Hz")
    body = eff - params.m2
    if body.size and not np.all(np.isfinite(body) & (body > 0)):
        k = int(np.flatnonzero(~(np.isfinite(body) & (body > 0)))[0])
        raise ParameterError(
            "moi_kgm2",
            float(eff[k]),
            f"I/Q^2 = {eff[k]:.4g} kg must exceed the barrel mass m2 = {params.m2:g} kg",
        )
    n = hoops.size
    P = np.tile(fast.kernel_params(Impact(params, speed, 1000.0, body_mass=1.0)), (n, 1))
    P[:, 6] = params.m2 * (2.0 * math.pi * hoops) ** 2
    P[:, 8] = 1.0 / body
    P[:, 9] = 1.0 / (params.m2 + body)
    v0 = np.full(n, speed)
    length = np.full(n, params.compression_scale(speed))
    n_active = np.full(n, 6, dtype=np.int64)
    t_max = np.asarray(contact_time_limit(params, speed, hoops), dtype=float)
    return fast._run_batch(P, v0, length, rtol, n_active, t_max, _LazyImpacts(params, speed, hoops, body))
