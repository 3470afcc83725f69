"""The bat population study (founding paper, section 5): datasets, store rows, bins, model, plots' data.

The names load on first use, so that a command needing only `rig.population.limits` does not
import the collision model.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rig.population.binning import Bin, bin_by_hoop
    from rig.population.dataset import COLUMNS, METRICS, PopulationBat, load_population, write_population_csv
    from rig.population.study import PopulationStudy, run_study

_WHERE = {
    "Bin": "binning",
    "bin_by_hoop": "binning",
    "COLUMNS": "dataset",
    "METRICS": "dataset",
    "PopulationBat": "dataset",
    "load_population": "dataset",
    "write_population_csv": "dataset",
    "PopulationStudy": "study",
    "run_study": "study",
}


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'rig.population' has no attribute {name!r}")
    return getattr(importlib.import_module(f"rig.population.{module}"), name)


__all__ = [
    "COLUMNS",
    "METRICS",
    "Bin",
    "PopulationBat",
    "PopulationStudy",
    "bin_by_hoop",
    "load_population",
    "run_study",
    "write_population_csv",
]
