"""CCOR data for the tests and the benchmark, made with the tests' own reference solver (not rig's)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from rig.ball.data import CcorPoint
from tests.ball.reference_ccor import PAPER, reference_ccor

SPEEDS = (25.0, 33.75, 42.5, 51.25, 60.0)  # m/s: five speeds spanning the paper's test
TRUE = {**PAPER, "a": 0.70, "b": 0.55}  # far from the paper's 0.6495, 0.5202 (where the fit starts)
NOISE = 0.0005  # CCOR, per ball
BALLS_PER_SPEED = 4


@cache
def true_ccor(speed: float, a: float = TRUE["a"], b: float = TRUE["b"]) -> float:
    """The reference CCOR of the true ball at one speed (cached: every seed reuses it)."""
    return reference_ccor(speed, **{**TRUE, "a": a, "b": b})


def ccor_points(
    seed: int,
    noise: float = NOISE,
    balls: int = BALLS_PER_SPEED,
    speeds: tuple[float, ...] = SPEEDS,
    with_u: bool = False,
) -> list[CcorPoint]:
    """`balls` balls at each speed (one shot each), each CCOR the truth plus Gaussian ball-to-ball scatter."""
    rng = np.random.default_rng(seed)
    out = []
    for i, v in enumerate(speeds):
        for j in range(balls):
            c = true_ccor(v) + float(rng.normal(0.0, noise))
            out.append(CcorPoint(v, c, noise if with_u else None, f"B{i}-{j}"))
    return out


def write_ccor_csv(path: Path, seed: int) -> Path:
    """A CCOR.csv of `ccor_points(seed, with_u=True)` (speed_m_s, ccor, u_ccor, ball_id), as a lab exports."""
    rows = ccor_points(seed=seed, with_u=True)
    lines = "".join(f"{p.speed_m_s},{p.ccor},{p.u_ccor},{p.ball_id}\n" for p in rows)
    path.write_text("speed_m_s,ccor,u_ccor,ball_id\n" + lines, encoding="utf-8")
    return path
