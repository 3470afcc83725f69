"""The bat population study (founding paper, section 5): datasets, store rows, bins, model, plots' data."""

from rig.population.binning import Bin, bin_by_hoop
from rig.population.dataset import COLUMNS, METRICS, PopulationBat, load_population, write_population_csv
from rig.population.study import PopulationStudy, run_study

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
