"""Populations of measured bats and the model's calibration against them: datasets, store rows, the
calibration file and the cross-check (the population study itself is studies.population).

The names load on first use, so that a command needing only `rig.population.limits` does not
import the collision model.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rig.core.lazy import lazy_names

if TYPE_CHECKING:
    from rig.population.dataset import COLUMNS, METRICS, PopulationBat, load_population, write_population_csv

_WHERE = {
    "COLUMNS": "dataset",
    "METRICS": "dataset",
    "PopulationBat": "dataset",
    "load_population": "dataset",
    "write_population_csv": "dataset",
}


__getattr__ = lazy_names(__name__, _WHERE)


__all__ = [
    "COLUMNS",
    "METRICS",
    "PopulationBat",
    "load_population",
    "write_population_csv",
]
