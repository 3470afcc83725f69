"""Normalized collision efficiency eta(f) = COR(f) / COR_rigid (the paper's Fig. 4) and its optimum."""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from rig.core.errors import ParameterError
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams, barrel_spring, check_hoop, check_speed, check_tolerance
from rig.physics.reference import contact_time_limit

REFINE_RTOL = 1e-12  # tighter than the grid so that solver noise cannot move the optimum


@dataclass(frozen=True)
class EfficiencyCurve:
    """eta on an even grid of hoop frequencies, and the optimum refined between grid points."""

    speed: float
    hoop_hz: np.ndarray
    cor: np.ndarray
    contact_time_s: np.ndarray
    cor_rigid: float
    efficiency: np.ndarray
    optimum_hz: float
    optimum_efficiency: float
    optimum_interior: bool  # False when the best point is an end of the grid
    rtol: float
    contacts: np.ndarray | None = None  # separate contacts at each grid point


def cor_grid(
    params: CollisionParams,
    speed: float,
    hoops: np.ndarray,
    rtol: float = fast.DEFAULT_RTOL,
    contacts: np.ndarray | None = None,
    evaluations: np.ndarray | None = None,
    series: int = fast.SERIES_ORDER,
) -> tuple[np.ndarray, np.ndarray]:
    """COR and contact time (to the last separation) of a clamped barrel at each hoop frequency,
    in parallel lanes; `contacts` and `evaluations`, if given, receive the number of contacts and of
    right-hand side evaluations at each. `series`: the contact's body in Taylor series steps of that
    order (`fast.solve_series`; 0: DOP853 steps throughout, `fast.solve`'s numbers to the last bit)."""
    speed = check_speed(speed)
    rtol = check_tolerance(rtol)
    hoops = np.asarray(hoops, dtype=float)
    if hoops.size and not (np.all(np.isfinite(hoops)) and np.all(hoops > 0)):
        bad = hoops[~(np.isfinite(hoops) & (hoops > 0))][0]
        raise ParameterError("hoop_hz", bad, "must be finite and > 0 Hz")
    base = fast.kernel_params(Impact(params, speed, 1.0))
    n = hoops.size
    P = np.tile(base, (n, 1))
    P[:, 6] = barrel_spring(params.m2, hoops)
    v0 = np.full(n, speed)
    length = np.full(n, params.compression_scale(speed))
    n_active = np.full(n, 4, dtype=np.int64)
    t_max = contact_time_limit(params, speed, hoops)
    impacts = _LazyImpacts(params, speed, hoops)
    return fast._run_batch(
        P, v0, length, rtol, n_active, t_max, impacts, contacts, evaluations=evaluations, series=series
    )


class _LazyImpacts:
    """Builds the Impact of lane k only when an error message needs it."""

    def __init__(self, params: CollisionParams, speed: float, hoops: np.ndarray) -> None:
        self._args = (params, speed, hoops)

    def __getitem__(self, k: int) -> Impact:
        params, speed, hoops = self._args
        return Impact(params, speed, float(hoops[k]))

    def __len__(self) -> int:
        return len(self._args[2])


def rigid_cor(params: CollisionParams, speed: float, rtol: float = REFINE_RTOL) -> float:
    """COR of the ball on a rigid, clamped barrel."""
    return fast.solve(Impact(params, speed), rtol=rtol).cor


def efficiency(params: CollisionParams, speed: float, hoop_hz: float, rtol: float = REFINE_RTOL) -> float:
    """eta at one hoop frequency."""
    cor = fast.solve(Impact(params, speed, hoop_hz), rtol=rtol).cor
    return cor / rigid_cor(params, speed, rtol)


def refine_optimum(
    params: CollisionParams,
    speed: float,
    lo: float,
    hi: float,
    cor_rigid: float,
    rtol: float = REFINE_RTOL,
) -> tuple[float, float]:
    """Maximize eta between lo and hi (bounded Brent); returns (hoop_hz, eta)."""

    def negative_eta(f: float) -> float:
        return -fast.solve(Impact(params, speed, f), rtol=rtol).cor / cor_rigid

    from scipy.optimize import minimize_scalar  # on first use: a single solve does not need it

    res = minimize_scalar(negative_eta, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
    return float(res.x), float(-res.fun)


def _bound(name: str, value: float) -> float:
    try:
        return check_hoop(value)
    except ParameterError as exc:
        raise ParameterError(name, value, exc.reason) from None


def efficiency_curve(
    params: CollisionParams,
    speed: float,
    hoop_min: float,
    hoop_max: float,
    points: int,
    rtol: float = fast.DEFAULT_RTOL,
    refine: bool = True,
) -> EfficiencyCurve:
    """eta at `points` evenly spaced hoop frequencies, with the optimum located between them."""
    hoop_min, hoop_max = _bound("hoop_min", hoop_min), _bound("hoop_max", hoop_max)
    if hoop_max <= hoop_min:
        raise ParameterError("hoop_max", hoop_max, f"must be greater than hoop_min ({hoop_min:g} Hz)")
    try:
        points = operator.index(points)
    except TypeError:
        raise ParameterError("points", points, "must be a whole number >= 2") from None
    if points < 2:
        raise ParameterError("points", points, "must be a whole number >= 2")
    hoops = np.linspace(hoop_min, hoop_max, points)
    contacts = np.ones(hoops.size, dtype=np.int64)
    cor, tc = cor_grid(params, speed, hoops, rtol, contacts)
    e_rigid = rigid_cor(params, speed)
    eta = cor / e_rigid
    i = int(np.argmax(eta))
    interior = 0 < i < points - 1
    f_opt, eta_opt = float(hoops[i]), float(eta[i])
    if refine and interior:
        f_opt, eta_opt = refine_optimum(
            params, speed, float(hoops[i - 1]), float(hoops[i + 1]), e_rigid, min(rtol, REFINE_RTOL)
        )
    return EfficiencyCurve(
        speed=speed,
        hoop_hz=hoops,
        cor=cor,
        contact_time_s=tc,
        cor_rigid=e_rigid,
        efficiency=eta,
        optimum_hz=f_opt,
        optimum_efficiency=eta_opt,
        optimum_interior=interior,
        rtol=rtol,
        contacts=contacts,
    )


__all__ = ["EfficiencyCurve", "cor_grid", "efficiency", "efficiency_curve", "refine_optimum", "rigid_cor"]
