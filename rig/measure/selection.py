"""Choosing a model variant by leave-one-out error, for the calibration and the ball-law fit alike.

Each variant is fitted to all the data and scored by its leave-one-out (LOO) errors; the simplest
identified variant whose mean squared LOO error is within one standard error of the best wins (the
one-standard-error rule). The units the errors are paired over are the caller's: a bat, or a ball
whose points were left out together.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sized
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

import numpy as np


class Fitted(Protocol):
    """What a variant's fit tells of itself."""

    @property
    def values(self) -> dict[str, float]: ...
    @property
    def scatter(self) -> float: ...
    @property
    def condition(self) -> float: ...
    def errors(self) -> dict[str, float]: ...


FitT = TypeVar("FitT", bound=Fitted)


@dataclass(frozen=True)
class VariantReport(Generic[FitT]):
    """A variant's fit to all the data and its leave-one-out errors (measured - predicted)."""

    fit: FitT
    loo_errors: np.ndarray
    identified: bool

    @property
    def loo_rmse(self) -> float:
        """Root mean square of the leave-one-out errors."""
        return float(np.sqrt(np.mean(self.loo_errors**2)))


def simplest_within_one_se(
    reports: Mapping[str, VariantReport[Any]],
    variants: Mapping[str, Sized],
    unit_squares: Callable[[np.ndarray], np.ndarray],
) -> str:
    """The simplest identified variant whose mean squared LOO error is within one SE of the best.

    SE: the standard error of the mean of the units' paired differences in squared LOO error
    (`unit_squares` turns a variant's LOO errors into one squared error per unit); among variants
    with as many parameters (`variants[name]`), the lower LOO error comes first.
    """
    usable = {k: r for k, r in reports.items() if r.identified}
    best = min(usable, key=lambda k: usable[k].loo_rmse)
    for name in sorted(usable, key=lambda k: (len(variants[k]), usable[k].loo_rmse)):
        diff = unit_squares(usable[name].loo_errors) - unit_squares(usable[best].loo_errors)
        se = float(np.std(diff, ddof=1) / math.sqrt(diff.size)) if diff.size > 1 else 0.0
        if float(np.mean(diff)) <= se:
            return name
    return best


def finite_or_none(x: float) -> float | None:
    """A number for JSON: None for nan and infinities."""
    return float(x) if math.isfinite(x) else None


def variant_rows(reports: Mapping[str, VariantReport[Any]]) -> list[dict[str, Any]]:
    """Every variant's parameters, uncertainties and scores, as a calibration or ball file records them."""
    return [
        {
            "variant": name,
            "parameters": rep.fit.values,
            "uncertainty": {k: finite_or_none(v) for k, v in rep.fit.errors().items()},
            "scatter": finite_or_none(rep.fit.scatter),
            "loo_rmse": finite_or_none(rep.loo_rmse),
            "identified": rep.identified,
            "condition_number": finite_or_none(rep.fit.condition),
        }
        for name, rep in reports.items()
    ]
