"""Collision model of the ball and the bat's barrel (founding paper, Eqs. 1-2), pure numpy/scipy.

Variants (see MODELS): the clamped flexible barrel of the paper, the rigid barrel (its own
model, the limit f_hoop -> infinity), and the barrel on a pivoted bat body.
"""

from rig.physics.bat import BatPrediction, PivotedBat, bbcor_from_ea, ea_from_bbcor, predict_bat
from rig.physics.curve import EfficiencyCurve, efficiency, efficiency_curve, rigid_cor
from rig.physics.equations import Impact
from rig.physics.fast import solve, solve_batch
from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from rig.physics.reference import CollisionResult, solve_reference

MODELS = {
    "barrel": "ball on the hoop-mode mass m2, spring k2 and damper c2 to a clamped base (Eqs. 1-2)",
    "rigid": "ball on a rigid, clamped barrel (the limit f_hoop -> infinity)",
    "pivoted": "hoop mode on a rigid bat body of effective mass I/Q^2, free to recoil",
    "pivoted-rigid": "rigid barrel on the pivoted bat body",
}

__all__ = [
    "DEFAULT_PARAMS",
    "MODELS",
    "BatPrediction",
    "CollisionParams",
    "CollisionResult",
    "EfficiencyCurve",
    "Impact",
    "PivotedBat",
    "bbcor_from_ea",
    "ea_from_bbcor",
    "efficiency",
    "efficiency_curve",
    "predict_bat",
    "rigid_cor",
    "solve",
    "solve_batch",
    "solve_reference",
]
