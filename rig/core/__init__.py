"""Domain types, units and errors shared by every layer; imports nothing else of ours."""

from rig.core.errors import ParameterError, RigError, SolverError
from rig.core.units import INCH, MPH, OUNCE

__all__ = ["INCH", "MPH", "OUNCE", "ParameterError", "RigError", "SolverError"]
