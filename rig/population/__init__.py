"""The bat population study (founding paper, section 5): datasets, store rows, bins, model, plots' data.

The names load on first use, so that a command needing only `rig.population.limits` does not
import the collision model.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rig.core.lazy import lazy_names

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


__getattr__ = lazy_names(__name__, _WHERE)


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
