"""The ratio g = dBBCOR/d(plate COR) that carries a lot's wear and air to a bat's hits, against the
simulated bat's own (issue 25): on the softball scene's lively 1500 Hz barrel a rigid barrel's g
(1.02) was 25 % above the simulator's (0.82), beyond the 15 % budgeted, and every fastpitch BPF's
wear and air corrections were that much too large."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.core.bat import BatSpec
from rig.physics import rigid_cor
from rig.protocols.ball_terms import G_U_REL, BallTerms, law_params, ratio
from rig.session import scene_with_bat
from rig.simulators.scene import Scene
from rig.simulators.truth import collision_of

ROOT = Path(__file__).resolve().parents[2]
SPEED = 26.82  # 60 mph, the BPF procedures' and the plate's


def simulated_g(scene: Scene, q: float) -> float:
    """The scene's own d BBCOR / d (plate COR) for the ball's damping c1 +1 %."""
    collide, ball, moi = collision_of(scene).collide, scene.ball, scene.bat.moi_kgm2
    k = ball.m1 * q * q / moi

    def both(scale: float) -> tuple[float, float]:
        p = ball.model_copy(update={"c1": ball.c1 * scale})
        e_a, _ = collide(p, SPEED, q)
        return e_a * (1 + k) + k, rigid_cor(p, SPEED)

    (b0, c0), (b1, c1) = both(1.0), both(1.01)
    return (b1 - b0) / (c1 - c0)


@pytest.mark.parametrize(
    ("scene_name", "bat_file", "ball_class", "mass_kg"),
    [("softball", "softball-bat.toml", "47/375", 0.187), ("lab", "sample-bat.toml", None, 0.145)],
)
def test_the_ratio_on_the_bats_barrel_is_the_simulated_bats_within_its_u(
    scene_name: str, bat_file: str, ball_class: str | None, mass_kg: float
) -> None:
    bat = BatSpec.load(ROOT / "protocols" / "examples" / bat_file)
    scene = scene_with_bat(Scene.load(ROOT / "simulators" / "scenes" / f"{scene_name}.toml"), bat)
    scene = scene.with_ball_class(ball_class)
    q = bat.impact_from_pivot_m(6.5)
    truth = simulated_g(scene, q)
    g = ratio(
        law_params(BallTerms(), mass_kg), "bbcor", SPEED, q, scene.bat.moi_kgm2, bat.length_m, bat.hoop_hz
    )
    assert abs(g - truth) <= 0.5 * G_U_REL * truth, (g, truth)  # well inside its 15 % u
