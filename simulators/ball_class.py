"""Softballs for the simulated cannon: a ball class (COR/compression, e.g. "44/375") as the model's ball.

A softball is named by its COR against a rigid wall at 60 mph and its compression load, lbf at
0.25 in (ASTM F1887, F1888) [C2]: "44/375" (12 in slow pitch), "52/300" (12 in, approved by USA
Softball 2010-2012) [C2], "47/375" (11 in fastpitch) [U]. The simulated ball of a class is the
scene's contact law (Eq. 1 of the founding paper) with

- m1: the class's mass, 6.6 oz (the middle of 6.25-7.0 oz [C2]) [U];
- k1: the scene's k1 times compression / 375 lbf: the paper's baseball taken as a 375 lbf ball and
  the dynamic stiffness proportional to the static load [U];
- c1: solved so that the ball's rigid-wall COR at 60 mph (rig.physics.rigid_cor) is the class's COR;
- a, b: the scene's (the paper's) exponents [U];

and its diameter (circumference / pi) is the drag effect's ball diameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.optimize import brentq

from rig.core.errors import ConfigError
from rig.core.units import INCH, MPH
from rig.physics import CollisionParams, rigid_cor

WALL_SPEED_M_S = 60.0 * MPH  # [C] the class's COR is measured at 60 mph on a rigid wall
REFERENCE_COMPRESSION_LBF = 375.0  # [U] the compression the scene's own (baseball) k1 stands for
SOFTBALL_MASS_KG = 0.187  # [U] 6.6 oz, the middle of 6.25-7.0 oz [C2]


@dataclass(frozen=True)
class BallClass:
    """A softball class: its COR at 60 mph on a rigid wall, compression (lbf) and size."""

    key: str  # "44/375"
    cor: float
    compression_lbf: float
    circumference_in: float
    mass_kg: float = SOFTBALL_MASS_KG

    @property
    def diameter_m(self) -> float:
        """The ball's diameter, m (circumference / pi)."""
        return self.circumference_in * INCH / math.pi

    def params(self, base: CollisionParams) -> CollisionParams:
        """The model's ball of this class: `base` with the class's m1, k1 and the c1 giving its COR."""
        k1 = base.k1 * self.compression_lbf / REFERENCE_COMPRESSION_LBF
        ball = base.model_copy(update={"m1": self.mass_kg, "k1": k1})

        def excess(c1: float) -> float:
            return rigid_cor(ball.model_copy(update={"c1": c1}), WALL_SPEED_M_S) - self.cor

        c1 = brentq(excess, 1.0, 1e5, xtol=1e-9, rtol=1e-12)  # COR falls with c1 from ~1 to ~0
        return ball.model_copy(update={"c1": float(c1)})


CLASSES: dict[str, BallClass] = {
    c.key: c
    for c in (
        BallClass("44/375", 0.44, 375.0, 12.0),  # [C2] slow pitch
        BallClass("52/300", 0.52, 300.0, 12.0),  # [C2] slow pitch, 2010-2012
        BallClass("47/375", 0.47, 375.0, 11.0),  # [U] fastpitch
    )
}


def ball_class(key: str) -> BallClass:
    """The class "NN/CCC" (a leading '.' allowed); ConfigError naming the known ones."""
    found = CLASSES.get(key.lstrip("."))
    if found is None:
        raise ConfigError(
            f"no simulated softball of class {key!r}; the simulator has {', '.join(CLASSES)}",
            source="ball_class",
        )
    return found
