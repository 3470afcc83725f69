"""Closed forms and identities of the paper's metrics (Eqs. 3-5) and the BESR kinematics."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core.errors import ParameterError
from rig.core.units import INCH, MPH
from rig.measure.metrics import (
    BESR_REFERENCE_SPEED_M_S,
    DEFINITIONS,
    SwingModel,
    bbcor,
    bbs,
    besr_eq3,
    compute_metrics,
    ea_from_bbcor,
)

L34 = 34 * INCH
e_as = st.floats(0.0, 0.95)
ks = st.floats(0.01, 2.0)


def test_worked_example_of_standards_md() -> None:
    # e_A 0.20 and k 0.25 give BBCOR 0.50: pick I so that m Q^2 / I = 0.25 exactly
    moi = 0.145 * 0.56**2 / 0.25
    m = compute_metrics(60.8, 0.2 * 60.8, 0.56, moi, 0.145, L34)
    assert m.e_a == pytest.approx(0.20, abs=1e-15)
    assert m.k == pytest.approx(0.25, abs=1e-15)
    assert m.bbcor == pytest.approx(0.50, abs=1e-15)
    assert m.besr == pytest.approx(0.70, abs=1e-15)


@given(e=e_as, k=ks)
def test_bbcor_inverse(e: float, k: float) -> None:
    assert ea_from_bbcor(bbcor(e, k), k) == pytest.approx(e, abs=1e-12)


@given(v_in=st.floats(20.0, 70.0), e=e_as, q=st.floats(0.3, 0.7), moi=st.floats(0.1, 0.4))
def test_bbcor_equals_relative_speed_ratio_with_angular_momentum(
    v_in: float, e: float, q: float, moi: float
) -> None:
    # Independent route (WSU definition): BBCOR = (v_r + omega Q) / v_i, omega = m Q (v_i + v_r) / I
    v_out = e * v_in
    omega = 0.145 * q * (v_in + v_out) / moi
    m = compute_metrics(v_in, v_out, q, moi, 0.145, L34)
    assert m.bbcor == pytest.approx((v_out + omega * q) / v_in, rel=1e-12)


@given(e=e_as, v=st.floats(10.0, 40.0), V=st.floats(10.0, 40.0))
def test_besr_standard_form_is_falcons_definition(e: float, v: float, V: float) -> None:
    # Falcon: BESR = [v* - (V - v)/2] / (V + v), v* the exit speed (Eq. 4 with V_bat = V)
    v_star = bbs(e, v, V)
    assert (v_star - (V - v) / 2) / (V + v) == pytest.approx(e + 0.5, rel=1e-12)


def test_besr_limit_0728_is_97_mph_with_the_original_kinematics() -> None:
    q = L34 - 12 * INCH  # the 6-in-from-tip point: bat speed is the reference 66 mph
    m = compute_metrics(60.8, 0.228 * 60.8, q, 0.19, 0.145, L34)
    assert m.v_bat == pytest.approx(66 * MPH, rel=1e-12)
    assert m.besr == pytest.approx(0.728)
    assert m.bbs / MPH == pytest.approx(97.0, abs=0.01)


@given(v_in=st.floats(20.0, 80.0), e=st.floats(0.0, 0.9))
def test_eq3_agrees_with_standard_form_only_when_dv_is_zero(v_in: float, e: float) -> None:
    v_out = e * v_in
    # dv = 60.8 m/s - V_contact = 0 when the contact point moves at the full 136 mph
    assert besr_eq3(v_in, v_out, BESR_REFERENCE_SPEED_M_S) == pytest.approx(e + 0.5, rel=1e-12, abs=1e-12)
    # anything else differs by dv (1 - e) / (v_in - dv) unless e = 1
    v_contact = 29.5
    dv = BESR_REFERENCE_SPEED_M_S - v_contact
    if abs(v_in - dv) > 1.0:
        diff = besr_eq3(v_in, v_out, v_contact) - (e + 0.5)
        assert diff == pytest.approx(-dv * (1 - e) / (v_in - dv), rel=1e-9)


def test_eq3_is_singular_when_v_contact_is_zero_at_the_reference_speed() -> None:
    # The tempting "forms agree at V_contact = 0" is false: there v_in = dv and Eq. 3 divides by zero.
    with pytest.raises(ParameterError, match="singular"):
        besr_eq3(BESR_REFERENCE_SPEED_M_S, 11.0, 0.0)
    swing = SwingModel(reference_speed_m_s=1e-12)  # V_contact ~ 0
    m = compute_metrics(BESR_REFERENCE_SPEED_M_S, 11.0, 0.56, 0.19, 0.145, L34, swing)
    assert m.besr_eq3 is None
    assert m.besr == pytest.approx(11.0 / BESR_REFERENCE_SPEED_M_S + 0.5)


@given(q=st.floats(0.3, 0.7))
def test_swing_speed_is_rigid_rotation(q: float) -> None:
    sw = SwingModel()
    assert sw.bat_speed(q, L34) == pytest.approx(66 * MPH * q / (L34 - 12 * INCH), rel=1e-12)


@given(loc_in=st.floats(4.0, 9.0), length_in=st.floats(31.0, 34.0))
def test_falcon_pivot_option_reproduces_falcons_adjustment(loc_in: float, length_in: float) -> None:
    # Falcon: V(6-in point) = V_contact (L - 11.375) / (L - 5.375 - Loc), Loc from the barrel end
    sw = SwingModel(swing_pivot_from_knob_m=5.375 * INCH)
    L, loc = length_in * INCH, loc_in * INCH
    q = L - 6 * INCH - loc  # rig pivot 6 in from the knob
    v_contact = sw.bat_speed(q, L)
    assert v_contact * (L - 11.375 * INCH) / (L - 5.375 * INCH - loc) == pytest.approx(66 * MPH, rel=1e-12)


def test_bbs_closed_form() -> None:
    m = compute_metrics(60.8, 12.16, 0.56, 0.19, 0.145, L34)
    v_bat = 66 * MPH * 0.56 / (22 * INCH)
    assert m.bbs == pytest.approx(70 * MPH * 0.2 + v_bat * 1.2, rel=1e-12)


@pytest.mark.parametrize(
    "args", [(0.0, 1.0), (-60.8, 11.0), (60.8, -1.0), (float("nan"), 11.0), (60.8, float("inf"))]
)
def test_bad_speeds_refused(args: tuple[float, float]) -> None:
    with pytest.raises(ParameterError):
        compute_metrics(*args, 0.56, 0.19, 0.145, L34)


def test_every_value_has_a_definition_with_formula_and_source() -> None:
    m = compute_metrics(60.8, 11.0, 0.56, 0.19, 0.145, L34, ball_cor=0.55)
    assert set(m.as_dict()) == set(DEFINITIONS) == set(m.definitions)
    # without a ball COR the BPF values (and the ball COR itself) are not computed, and nothing else goes
    bare = compute_metrics(60.8, 11.0, 0.56, 0.19, 0.145, L34)
    assert set(DEFINITIONS) - set(bare.as_dict()) == {"ball_cor", "usssa_bpf", "fastpitch_bpf"}
    for text in DEFINITIONS.values():
        assert "=" in text and "(" in text
    assert (
        "Eq. 5" in DEFINITIONS["bbcor"]
        and "Eq. 4" in DEFINITIONS["bbs"]
        and "Eq. 3" in DEFINITIONS["besr_eq3"]
    )
