"""The pivoted bat: Eq. 5 (BBCOR), momentum conservation and the rigid body's reduced-mass identity."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core.errors import ParameterError
from rig.physics import fast
from rig.physics.bat import PivotedBat, bbcor_from_ea, ea_from_bbcor, impact_for, predict_bat
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams
from rig.physics.reference import momentum, solve_reference

# a typical BBCOR bat on the rig: I about the 6-inch pivot, impact 21 in (0.533 m) from the pivot
BAT = PivotedBat.build(moi_kgm2=0.19, impact_from_pivot_m=0.5334)


def test_effective_mass_and_recoil_factor() -> None:
    """M = I/Q^2 and k = m_ball Q^2 / I (Eq. 5)."""
    assert BAT.effective_mass == pytest.approx(0.19 / 0.5334**2, rel=1e-15)
    assert BAT.recoil_factor(0.145) == pytest.approx(0.145 * 0.5334**2 / 0.19, rel=1e-15)


@given(e_a=st.floats(-1.0, 1.0), k=st.floats(0.0, 10.0))
def test_bbcor_identity_and_inverse(e_a: float, k: float) -> None:
    """BBCOR = e_A (1 + k) + k, and ea_from_bbcor undoes it."""
    bbcor = bbcor_from_ea(e_a, k)
    assert bbcor == pytest.approx(e_a * (1.0 + k) + k, rel=1e-12, abs=1e-12)
    assert ea_from_bbcor(bbcor, k) == pytest.approx(e_a, abs=1e-12)


def test_bbcor_of_a_perfect_and_a_dead_collision() -> None:
    """e_A = 1 gives BBCOR = 1 + 2k (a ball gains recoil), e_A = -k/(1+k) gives BBCOR = 0."""
    assert bbcor_from_ea(1.0, 0.25) == pytest.approx(1.5)
    assert bbcor_from_ea(-0.25 / 1.25, 0.25) == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("hoop", [None, 300.0, 1250.0, 2800.0, 1e5])
@pytest.mark.parametrize("speed", [1.0, 60.8])
def test_momentum_is_conserved(paper_params: CollisionParams, hoop: float | None, speed: float) -> None:
    """Ball + hoop mass + body carry the inbound momentum m1 v0 away, in both solvers."""
    imp = impact_for(paper_params, speed, hoop, BAT)
    p0 = paper_params.m1 * speed
    res_fast = fast.solve(imp)
    res_ref = solve_reference(imp, "DOP853", 1e-10, energy=True)
    assert momentum(imp, res_fast.final_state) == pytest.approx(p0, rel=1e-12)
    assert momentum(imp, res_ref.final_state) == pytest.approx(p0, rel=1e-12)
    # independent of reference.momentum: sum m v over the state vector by hand
    s = res_fast.final_state
    if hoop is None:
        by_hand = paper_params.m1 * s[1] + BAT.effective_mass * s[3]
    else:
        by_hand = (
            paper_params.m1 * s[1] + paper_params.m2 * s[3] + (BAT.effective_mass - paper_params.m2) * s[5]
        )
    assert by_hand == pytest.approx(p0, rel=1e-12)
    assert res_fast.cor == pytest.approx(res_ref.cor, abs=1e-8)
    assert abs(res_ref.energy["residual"]) < 1e-8 * res_ref.energy["inbound_kinetic"]


@given(
    speed=st.floats(0.01, 100.0),
    hoop=st.none() | st.floats(100.0, 1e5),
    moi=st.floats(0.05, 0.5),
    q=st.floats(0.3, 0.7),
)
def test_pivoted_bat_bounds(speed: float, hoop: float | None, moi: float, q: float) -> None:
    """Any bat: momentum conserved, and BBCOR (from the bat's momentum) = Eq. 5 and <= 1.

    The bat's velocity at the impact point is its momentum over I/Q^2; energy conservation of the
    centre-of-mass motion then bounds the relative-velocity COR by 1.
    """
    params = CollisionParams()
    bat = PivotedBat.build(moi_kgm2=moi, impact_from_pivot_m=q)  # I/Q^2 >= 0.10 kg > m2
    imp = impact_for(params, speed, hoop, bat)
    res = fast.solve(imp)
    p0 = params.m1 * speed
    p_final = momentum(imp, res.final_state)
    assert p_final == pytest.approx(p0, rel=1e-11)
    v_ball = res.final_state[1]
    v_bat = (p_final - params.m1 * v_ball) / bat.effective_mass
    bbcor = bbcor_from_ea(res.cor, bat.recoil_factor(params.m1))
    assert bbcor == pytest.approx((v_bat - v_ball) / speed, abs=1e-9)
    assert -1.0 < res.cor <= 1.0
    assert bbcor <= 1.0 + 1e-7


@pytest.mark.parametrize("speed", [0.1, 26.8, 60.8])
def test_rigid_pivoted_bbcor_is_the_relative_velocity_cor(
    paper_params: CollisionParams, speed: float
) -> None:
    """Eq. 5 from the model's e_A equals (v_bat - v_ball)/v0 read off the final state."""
    imp = impact_for(paper_params, speed, None, BAT)
    res = fast.solve(imp, 1e-12)
    v_ball, v_bat = res.final_state[1], res.final_state[3]
    k = BAT.recoil_factor(paper_params.m1)
    assert bbcor_from_ea(res.cor, k) == pytest.approx((v_bat - v_ball) / speed, abs=1e-10)


@pytest.mark.parametrize("speed", [0.1, 26.8, 60.8])
def test_rigid_pivoted_bat_is_a_reduced_mass_collision(paper_params: CollisionParams, speed: float) -> None:
    """Ball on a free rigid mass M: the compression obeys mu d'' = -F with mu = m1 M/(m1 + M).

    So the relative-velocity COR (BBCOR) equals the rigid-wall COR of a ball of mass mu, and the
    model's e_A must be ea_from_bbcor of it; the contact times agree too.
    """
    M = BAT.effective_mass
    mu = paper_params.m1 * M / (paper_params.m1 + M)
    wall = fast.solve(Impact(paper_params.model_copy(update={"m1": mu}), speed), 1e-12)
    wall_ref = solve_reference(Impact(paper_params.model_copy(update={"m1": mu}), speed), "DOP853", 1e-12)
    assert wall.cor == pytest.approx(wall_ref.cor, abs=1e-9)
    pred = predict_bat(paper_params, speed, None, BAT, rtol=1e-12)
    k = BAT.recoil_factor(paper_params.m1)
    assert pred.e_a == pytest.approx(ea_from_bbcor(wall.cor, k), abs=1e-9)
    assert pred.bbcor == pytest.approx(wall.cor, abs=1e-9)
    assert pred.contact_time_s == pytest.approx(wall.contact_time_s, rel=1e-8)


def test_prediction_fields(paper_params: CollisionParams) -> None:
    """BESR = e_A + 1/2; the prediction reports k, I/Q^2 and the inputs."""
    pred = predict_bat(paper_params, 60.8, 1250.0, BAT)
    assert pred.besr == pytest.approx(pred.e_a + 0.5)
    assert pred.k == pytest.approx(BAT.recoil_factor(paper_params.m1))
    assert pred.effective_mass_kg == pytest.approx(BAT.effective_mass)
    assert pred.bbcor == pytest.approx(bbcor_from_ea(pred.e_a, pred.k))
    assert (pred.speed, pred.hoop_hz) == (60.8, 1250.0)
    assert pred.contact_time_s > 0.0


@pytest.mark.parametrize("speed", [26.8, 60.8])
def test_hoop_near_optimum_outperforms_a_stiff_barrel(paper_params: CollisionParams, speed: float) -> None:
    """Paper, section 5: lower hoop frequency (toward ~1250 Hz) means higher BBCOR than at 2800 Hz."""
    near = predict_bat(paper_params, speed, 1300.0, BAT).bbcor
    stiff = predict_bat(paper_params, speed, 2800.0, BAT).bbcor
    rigid = predict_bat(paper_params, speed, None, BAT).bbcor
    assert near > stiff > rigid


def test_bbcor_falls_from_1400_to_2800_hz(paper_params: CollisionParams) -> None:
    """Over the measured bats' range (1400-2800 Hz) BBCOR decreases with hoop frequency (Fig. 6)."""
    values = [predict_bat(paper_params, 60.8, f, BAT).bbcor for f in (1400.0, 1800.0, 2200.0, 2800.0)]
    assert all(hi > lo for hi, lo in itertools.pairwise(values))


@pytest.mark.parametrize("moi", [0.0225, 0.01])  # I/Q^2 = m2 exactly (Q = 0.5 m), and below it
def test_body_lighter_than_the_hoop_mass_is_refused(paper_params: CollisionParams, moi: float) -> None:
    """I/Q^2 <= m2 leaves no rigid body to carry the hoop mode: refused, naming the MOI."""
    bat = PivotedBat.build(moi_kgm2=moi, impact_from_pivot_m=0.5)
    for call in (
        lambda: impact_for(paper_params, 60.8, 1250.0, bat),
        lambda: predict_bat(paper_params, 60.8, None, bat),
    ):
        with pytest.raises(ParameterError) as exc:
            call()
        assert exc.value.name == "moi_kgm2"
        assert "m2" in str(exc.value)


def test_body_just_heavier_than_the_hoop_mass_solves(paper_params: CollisionParams) -> None:
    """I/Q^2 slightly above m2: a 1 g body, still a valid model that conserves momentum."""
    bat = PivotedBat.build(moi_kgm2=(paper_params.m2 + 1e-3) * 0.25, impact_from_pivot_m=0.5)
    imp = impact_for(paper_params, 60.8, 1250.0, bat)
    assert imp.body_mass == pytest.approx(1e-3)
    res = fast.solve(imp)
    assert math.isfinite(res.cor) and -1.0 < res.cor <= 1.0
    assert momentum(imp, res.final_state) == pytest.approx(paper_params.m1 * 60.8, rel=1e-12)
