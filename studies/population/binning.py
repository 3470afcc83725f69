"""Averages of a metric over hoop-frequency bins (the founding paper's Fig. 6).

Bins are centred on multiples of `width_hz`; a bin averages the bats whose hoop frequency lies in
[centre - half_width_hz, centre + half_width_hz). The paper: 50 Hz increments, averaged over
+-25 Hz, so each bat falls in exactly one bin. Empty bins are left out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from rig.core.errors import ParameterError


@dataclass(frozen=True)
class Bin:
    """One bin: its centre and edges, how many bats, their mean and sample standard deviation."""

    center_hz: float
    lo_hz: float
    hi_hz: float
    n: int
    mean: float
    std: float | None  # None for a single bat

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return asdict(self)


def bin_by_hoop(
    hoop_hz: Sequence[float],
    values: Sequence[float | None],
    width_hz: float = 50.0,
    half_width_hz: float = 25.0,
) -> list[Bin]:
    """Mean and spread of `values` in hoop-frequency bins; pairs with a None value are skipped."""
    if not (width_hz > 0 and half_width_hz > 0):
        raise ParameterError("width_hz", (width_hz, half_width_hz), "bin width and half width must be > 0")
    if len(hoop_hz) != len(values):
        raise ParameterError("values", len(values), f"need one value per hoop frequency ({len(hoop_hz)})")
    pairs = [(float(h), float(v)) for h, v in zip(hoop_hz, values, strict=True) if v is not None]
    if not pairs:
        return []
    h = np.array([p[0] for p in pairs])
    v = np.array([p[1] for p in pairs])
    first = math.floor((h.min() - half_width_hz) / width_hz)
    last = math.ceil((h.max() + half_width_hz) / width_hz)
    bins = []
    for k in range(first, last + 1):
        c = k * width_hz
        inside = (h >= c - half_width_hz) & (h < c + half_width_hz)
        n = int(inside.sum())
        if n == 0:
            continue
        std = float(np.std(v[inside], ddof=1)) if n > 1 else None
        bins.append(Bin(c, c - half_width_hz, c + half_width_hz, n, float(v[inside].mean()), std))
    return bins
