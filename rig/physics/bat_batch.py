"""Many pivoted bats under one or more sets of constants: the kernel's lanes built as arrays, not Impacts.

A calibration solves every bat of a population once per model evaluation; building an Impact
(and its checks) per bat cost about a third of each evaluation at 1,000 bats. Here the lanes of
one constant set are one row of kernel parameters tiled, with each bat's barrel spring
k2 = m2 (2 pi f)^2, body 1/(I/Q^2 - m2) and base 1/(I/Q^2) filled in as columns, as
`curve.cor_grid` does for the clamped barrel. The numbers are those of `solve_batch` over
`impact_for` (tests/physics/test_bat_batch.py holds them equal). Several sets of constants (a
prediction and its parameter steps) go in one batch: each lane's numbers do not depend on the others.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rig.core.errors import ParameterError
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams, barrel_spring, check_speed, check_tolerance
from rig.physics.reference import contact_time_limit


class _LazyImpacts:
    """The Impact of lane k (set k // n, bat k % n), built only when an error message needs it."""

    def __init__(
        self, sets: Sequence[CollisionParams], speed: float, hoops: np.ndarray, eff: np.ndarray
    ) -> None:
        self._args = (sets, speed, hoops, eff)

    def __getitem__(self, k: int) -> Impact:
        sets, speed, hoops, eff = self._args
        params, i = sets[k // hoops.size], k % hoops.size
        return Impact(params, speed, float(hoops[i]), body_mass=float(eff[i] - params.m2))


def pivoted_cor_batch(
    params: CollisionParams,
    speed: float,
    hoop_hz: np.ndarray,
    effective_mass: np.ndarray,
    rtol: float = fast.DEFAULT_RTOL,
) -> tuple[np.ndarray, np.ndarray]:
    """e_A and contact time of the ball on each pivoted bat (hoop frequency, I/Q^2) in parallel lanes."""
    cor, tc = pivoted_cor_sets([params], speed, hoop_hz, effective_mass, rtol)
    return cor[0], tc[0]


def _lanes_of(params: CollisionParams, speed: float, hoops: np.ndarray, eff: np.ndarray) -> np.ndarray:
    """The kernel's parameter rows of every bat under one set of constants."""
    body = eff - params.m2
    if body.size and not np.all(np.isfinite(body) & (body > 0)):
        k = int(np.flatnonzero(~(np.isfinite(body) & (body > 0)))[0])
        raise ParameterError(
            "moi_kgm2",
            float(eff[k]),
            f"I/Q^2 = {eff[k]:.4g} kg must exceed the barrel mass m2 = {params.m2:g} kg",
        )
    P = np.tile(fast.kernel_params(Impact(params, speed, 1000.0, body_mass=1.0)), (hoops.size, 1))
    P[:, 6] = barrel_spring(params.m2, hoops)
    P[:, 8] = 1.0 / body
    P[:, 9] = 1.0 / (params.m2 + body)
    return P


def pivoted_cor_sets(
    sets: Sequence[CollisionParams],
    speed: float,
    hoop_hz: np.ndarray,
    effective_mass: np.ndarray,
    rtol: float = fast.DEFAULT_RTOL,
    numpy_lanes: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """pivoted_cor_batch under each set of constants (rows), every set's bats in one batch of lanes.

    numpy_lanes: as `fast.solve_batch`'s (a small batch in numpy, without loading numba).
    """
    speed = check_speed(speed)
    rtol = check_tolerance(rtol)
    hoops = np.asarray(hoop_hz, dtype=float)
    eff = np.asarray(effective_mass, dtype=float)
    if hoops.size and not (np.all(np.isfinite(hoops)) and np.all(hoops > 0)):
        bad = hoops[~(np.isfinite(hoops) & (hoops > 0))][0]
        raise ParameterError("hoop_hz", float(bad), "must be finite and > 0 Hz")
    if not sets:
        return np.empty((0, hoops.size)), np.empty((0, hoops.size))
    n = hoops.size * len(sets)
    P = np.concatenate([_lanes_of(params, speed, hoops, eff) for params in sets])
    v0 = np.full(n, speed)
    length = np.concatenate([np.full(hoops.size, p.compression_scale(speed)) for p in sets])
    n_active = np.full(n, 6, dtype=np.int64)
    t_max = np.concatenate(
        [np.asarray(contact_time_limit(p, speed, hoops), dtype=float).reshape(hoops.size) for p in sets]
    )
    cor, tc = fast._run_batch(
        P, v0, length, rtol, n_active, t_max, _LazyImpacts(sets, speed, hoops, eff), numpy_lanes=numpy_lanes
    )
    return cor.reshape(len(sets), hoops.size), tc.reshape(len(sets), hoops.size)
