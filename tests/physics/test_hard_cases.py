"""Hard corners of the collision model: stability, physical bounds, solver agreement, convergence.

Property tests draw from: hoop 100 Hz .. 1 MHz (log-uniform) and the rigid barrel; speed
0.01 .. 100 m/s; exponents a, b at 0, at 1 and between; c1 = 0 and c2 = 0; barrel mass m2 from
1e-4 kg to 1e4 kg (explicit tests reach 1e8 kg). Below ~1e-5 kg with b = 0 the damping rate c1/m2
(> 5e8 /s) makes the model stiff, so the explicit kernel runs out of steps; and a barrel much
lighter than the ball rides its spring for ~pi sqrt(m1/k2): the time limit grows with sqrt(m1/m2).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import currently_in_test_context, event, example, given, note
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from rig.core.errors import SolverError
from rig.physics import curve, fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams
from rig.physics.reference import CollisionResult, solve_reference

# --- strategies ----------------------------------------------------------------------------------


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Floats spread evenly in log between lo and hi."""
    return st.floats(math.log(lo), math.log(hi)).map(lambda x: min(max(math.exp(x), lo), hi))


EXPONENT = st.one_of(st.sampled_from([0.0, 1.0]), st.floats(0.0, 1.0))
BALL_DAMPING = st.one_of(st.sampled_from([0.0, 5000.0]), log_uniform(1.0, 1e5))
BARREL_DAMPING = st.one_of(st.sampled_from([0.0, 100.0]), log_uniform(1.0, 1e4))
SPEED = st.one_of(st.sampled_from([0.01, 100.0]), log_uniform(0.01, 100.0))


@st.composite
def impacts(draw: st.DrawFn, m2_lo: float, m2_hi: float, hoop_hi: float) -> Impact:
    """A clamped collision from the hard-corner space (hoop None = rigid barrel)."""
    params = CollisionParams.build(
        m2=draw(st.one_of(st.just(0.09), log_uniform(m2_lo, m2_hi))),
        a=draw(EXPONENT),
        b=draw(EXPONENT),
        c1=draw(BALL_DAMPING),
        c2=draw(BARREL_DAMPING),
    )
    hoop = draw(st.one_of(st.none(), st.sampled_from([100.0, hoop_hi]), log_uniform(100.0, hoop_hi)))
    return Impact(params, draw(SPEED), hoop)


# --- physical checks shared by the property tests ------------------------------------------------

COR_SLACK = 1e-7  # solver error allowed beyond a hard physical bound (rtol 1e-10)


def full_state(imp: Impact, res: CollisionResult) -> np.ndarray:
    """[x1, v1, x2, v2] at separation (barrel at rest at 0 for the rigid clamped model)."""
    y = np.zeros(4)
    n = 2 if imp.rigid else 4
    y[:n] = res.final_state[:n]
    return y


def energy_out(imp: Impact, y: np.ndarray) -> float:
    """Mechanical energy left at separation: ball kinetic + ball stored + barrel kinetic and spring."""
    p = imp.params
    d = abs(y[0] - y[2])
    e = 0.5 * p.m1 * y[1] ** 2 + p.k1 * d ** (2.0 + p.a) / (2.0 + p.a)
    if not imp.rigid:
        e += 0.5 * p.m2 * y[3] ** 2 + 0.5 * imp.k2 * y[2] ** 2
    return e


def check_physical(imp: Impact, res: CollisionResult) -> None:
    """Bounds every clamped collision must respect, whatever the parameters."""
    p = imp.params
    y = full_state(imp, res)
    if currently_in_test_context():
        note(f"{imp!r} -> COR {res.cor!r}, contact {res.contact_time_s!r} s, state {y}")
    assert math.isfinite(res.cor)
    assert math.isfinite(res.contact_time_s)
    assert np.all(np.isfinite(y))
    # the solver never stops at t = 0 (that would report COR = -1 with the ball untouched)
    assert res.contact_time_s > 0.0
    assert res.cor > -1.0
    # a passive barrel cannot return more energy than came in, so |COR| <= 1
    assert res.cor <= 1.0 + COR_SLACK
    e_in = 0.5 * p.m1 * imp.speed**2
    e_out = energy_out(imp, y)
    length = p.compression_scale(imp.speed)
    # The barrel's position is controlled only to atol = rtol * length, so a very stiff barrel's
    # spring can hold noise energy ~ k2 atol^2 / 2 (e.g. 7e-7 of the inbound KE for m2 = 3.7 t
    # at 1 MHz and 0.01 m/s). The COR is unaffected; the energy check allows for it.
    noise = 0.0 if imp.rigid else 10.0 * 0.5 * imp.k2 * (res.rtol * length) ** 2
    assert e_out <= e_in * (1.0 + COR_SLACK) + noise
    if p.c1 == 0.0 and (imp.rigid or p.c2 == 0.0):
        assert e_out == pytest.approx(e_in, rel=COR_SLACK, abs=noise)
    # At separation F = 0, so c1 d' = -k1 d|d|^(a-b): the ball recedes from the barrel surface
    # (d' <= 0) and, with c1 > 0, is still compressed (d > 0).
    assert y[1] - y[3] <= COR_SLACK * imp.speed
    assert y[0] - y[2] >= -COR_SLACK * length
    if imp.rigid:
        # The barrel is fixed, so receding from it means rebounding: COR >= 0. A flexible barrel can
        # still be moving forward at separation and the ball with it (v1 < v2 but v1 > 0), so there
        # COR < 0 is physical (the ball leaves for good only if the barrel cannot catch it up).
        if p.c1 > 0.0:
            assert res.cor >= 0.0
        else:
            assert res.cor == pytest.approx(1.0, abs=COR_SLACK)


# --- property tests ------------------------------------------------------------------------------


@given(imp=impacts(m2_lo=1e-4, m2_hi=1e4, hoop_hi=1e6))
def test_fast_solver_respects_physical_bounds(imp: Impact) -> None:
    """Compiled solver over the whole hard-corner space: finite, bounded, energy never created."""
    check_physical(imp, fast.solve(imp))


@given(imp=impacts(m2_lo=1e-2, m2_hi=1e2, hoop_hi=2e5))
def test_solvers_agree_and_energy_balances(imp: Impact) -> None:
    """Fast (rtol 1e-10) matches scipy DOP853 (1e-12); scipy's energy books balance to 1e-8 of KE.

    The space is narrower than above because the scipy solver costs up to ~1 s near 1 MHz or
    below 1e-2 kg. Agreement is demanded where the answer is well conditioned, i.e. where scipy
    gives the same value at rtol 1e-11 and 1e-12. It is not, for example, when the ball creeps off
    an over-damped contact (COR ~ 1e-7: F stays ~0 for a long time, so the contact time is ill
    defined) or when F grazes zero before separating (see the grazing test below).
    """
    res_fast = fast.solve(imp, 1e-10)
    res_ref = solve_reference(imp, "DOP853", 1e-12, energy=True)
    res_check = solve_reference(imp, "DOP853", 1e-11)
    check_physical(imp, res_ref)
    if abs(res_ref.cor - res_check.cor) < 1e-8:
        assert res_fast.cor == pytest.approx(res_ref.cor, abs=2e-6)
    else:
        event("COR ill-conditioned")
    if res_ref.contact_time_s == pytest.approx(res_check.contact_time_s, rel=1e-7):
        assert res_fast.contact_time_s == pytest.approx(res_ref.contact_time_s, rel=1e-4)
    else:
        event("contact time ill-conditioned")
    books = res_ref.energy
    assert abs(books["residual"]) <= 1e-8 * books["inbound_kinetic"]
    assert books["ball_dissipated"] >= -1e-8 * books["inbound_kinetic"]
    assert books["barrel_dissipated"] >= -1e-8 * books["inbound_kinetic"]
    stored = energy_out(imp, full_state(imp, res_ref))
    left = sum(books[k] for k in ("ball_kinetic", "ball_stored", "barrel_kinetic", "barrel_stored"))
    assert left == pytest.approx(stored, rel=1e-9, abs=1e-12 * books["inbound_kinetic"])


@given(
    a=EXPONENT,
    b=EXPONENT,
    speed=SPEED,
    k1=log_uniform(1e4, 1e9),
    m1=log_uniform(0.01, 1.0),
)
def test_undamped_ball_on_rigid_barrel_rebounds_elastically(
    a: float, b: float, speed: float, k1: float, m1: float
) -> None:
    """c1 = 0 on a rigid barrel: nothing dissipates, so COR = 1 (c2 is irrelevant there).

    At rtol 1e-10 the error reaches ~1.5e-8 for fractional a (the force d^(1+a) is not smooth
    at the onset and at separation), hence the 1e-7 allowance.
    """
    params = CollisionParams.build(m1=m1, k1=k1, a=a, b=b, c1=0.0, c2=0.0)
    imp = Impact(params, speed)
    assert fast.solve(imp, 1e-10).cor == pytest.approx(1.0, abs=COR_SLACK)
    assert solve_reference(imp, "DOP853", 1e-10).cor == pytest.approx(1.0, abs=COR_SLACK)


RIGID_LIMIT_HOOPS = np.geomspace(2e4, 1e6, 6)
NOISE = 1e-9  # COR noise of the solvers at rtol 1e-12


@given(speed=SPEED, a=EXPONENT, b=EXPONENT, c1=st.sampled_from([0.0, 5000.0]) | log_uniform(100.0, 2e4))
# b = 0, a = 1, an over-damped ball: it creeps off at 1.4e-6 m/s while a 1 MHz barrel rings under it
# (27 attometres): ~85 touches, each ~1 us, change the COR by 1.6e-10 in all (a clipped-force solve
# agrees). Following them once stepped over a touch and ran to the time limit ("contact did not end").
@example(speed=1.0, a=1.0, b=0.0, c1=9652.93130545939)
def test_rigid_barrel_is_the_limit_of_the_flexible_one(speed: float, a: float, b: float, c1: float) -> None:
    """Over all exponents: |COR(1 MHz) - COR_rigid| < 2e-5 and smaller than at 20 kHz and 96 kHz.

    The approach need not be monotone here: with a ~ 0 and a short contact (f T_contact < ~50),
    the barrel's ringing at separation adds a term that changes sign with f, so |COR - COR_rigid|
    can grow between neighbouring frequencies (e.g. a = b = 0, c1 = 9327: 1.3e-4 at 96 kHz,
    4.9e-4 at 124 kHz), in both solvers alike.
    """
    params = CollisionParams.build(a=a, b=b, c1=c1)
    rigid = fast.solve(Impact(params, speed), 1e-12).cor
    try:  # the three hoops the assertions read (20 kHz, 96 kHz, 1 MHz): each lane solves alone
        cor, _ = curve.cor_grid(params, speed, RIGID_LIMIT_HOOPS[[0, 2, -1]], 1e-12)
    except SolverError as exc:
        # b ~ 0 only (the issue allows a refusal at b = 0): an over-damped ball creeping off at
        # ~1e-9 m/s (0.01 m/s in, COR ~ 1e-7) is touched again and again by the ringing barrel for
        # seconds (seen at a = 1, b = 1e-12, c1 = 10810, 95.6 kHz)
        assert b < 1e-6 and "creeps off" in str(exc)
        return
    gap = np.abs(cor - rigid)
    note(f"gaps {gap}")
    assert gap[-1] < 2e-5
    assert gap[-1] < max(min(gap[0], gap[1]), NOISE)


@given(
    speed=SPEED,
    m2=log_uniform(0.01, 10.0),
    c2=st.sampled_from([0.0, 100.0]) | log_uniform(1.0, 1e4),
)
def test_paper_ball_approaches_rigid_limit_monotonically(speed: float, m2: float, c2: float) -> None:
    """With the paper's ball the gap to the rigid COR falls at every step from 20 kHz to 1 MHz."""
    params = CollisionParams.build(m2=m2, c2=c2)
    rigid = fast.solve(Impact(params, speed), 1e-12).cor
    cor, _ = curve.cor_grid(params, speed, RIGID_LIMIT_HOOPS, 1e-12)
    gap = np.abs(cor - rigid)
    note(f"gaps {gap}")
    assert gap[-1] < 2e-5
    resolved = gap > NOISE
    assert np.all(np.diff(gap[resolved]) < 0.0)


@pytest.mark.parametrize("hoop", [None, 200.0, 1250.0, 5000.0, 5e4])
@pytest.mark.parametrize("speed", [0.01, 26.8, 100.0])
def test_energy_books_balance_for_the_paper_ball(
    paper_params: CollisionParams, hoop: float | None, speed: float
) -> None:
    """Inbound KE = what is left + what the ball and barrel dampers took, to 1e-8 (rtol 1e-10)."""
    imp = Impact(paper_params, speed, hoop)
    res = solve_reference(imp, "DOP853", 1e-10, energy=True)
    books = res.energy
    ke_in = 0.5 * paper_params.m1 * speed**2
    assert books["inbound_kinetic"] == pytest.approx(ke_in, rel=1e-15)
    assert abs(books["residual"]) <= 1e-8 * ke_in
    assert books["ball_dissipated"] > 0.0
    assert books["barrel_dissipated"] >= 0.0
    assert books["ball_kinetic"] == pytest.approx(res.cor**2 * ke_in, rel=1e-12)
    assert energy_out(imp, full_state(imp, res)) == pytest.approx(
        books["ball_kinetic"] + books["ball_stored"] + books["barrel_kinetic"] + books["barrel_stored"],
        rel=1e-12,
    )
    if hoop is None:  # all the lost KE is either dissipated in the ball or still stored in it
        assert books["ball_dissipated"] + books["ball_stored"] == pytest.approx(
            (1 - res.cor**2) * ke_in, rel=1e-8
        )


def test_reference_solver_near_rigid_hoop(paper_params: CollisionParams) -> None:
    """The stiff 1 MHz hoop with scipy's DOP853 agrees with the rigid model to 1e-6 (numerics.md 1.3)."""
    rigid = solve_reference(Impact(paper_params, 60.8), "DOP853", 1e-9).cor
    res = solve_reference(Impact(paper_params, 60.8, 1e6), "DOP853", 1e-9)
    assert res.cor == pytest.approx(rigid, abs=1e-6)
    assert res.contact_time_s == pytest.approx(0.580e-3, rel=2e-3)


# --- extreme barrels -----------------------------------------------------------------------------


# (m2, hoop, largest |COR - COR_rigid| expected; None: no rigid-like behaviour expected)
EXTREME_BARRELS = [
    (1e-4, 100.0, None),  # 0.1 g on a soft spring: over-damped by c2 (c2/m2 = 1e6 /s)
    (1e-4, 1e6, 2e-3),  # 0.1 g on a very stiff spring: nearly rigid
    (1e4, 100.0, 1e-4),  # 10 t: hardly moves
    (1e8, 100.0, 1e-6),
    (1e8, 1e6, 1e-6),
]


@pytest.mark.parametrize(("m2", "hoop", "rigid_gap"), EXTREME_BARRELS)
@pytest.mark.parametrize("speed", [0.01, 100.0])
@pytest.mark.parametrize("b", [0.0, 0.5202])
def test_extreme_barrel_masses_solve(
    m2: float, hoop: float, rigid_gap: float | None, speed: float, b: float
) -> None:
    """Very light (0.1 g) and very heavy (10 t, 1e5 t) barrels solve with sane results."""
    imp = Impact(CollisionParams.build(m2=m2, b=b), speed, hoop)
    if rigid_gap is None:
        # over-damped 0.1 g barrel: the ball may creep off it (COR ~ 1e-3) for seconds of free
        # flight at a stiff rate c2/m2 = 1e6 /s; following that is refused with a message
        try:
            res = fast.solve(imp)
        except SolverError as exc:
            assert "creeps off" in str(exc)
            return
    else:
        res = fast.solve(imp)
    check_physical(imp, res)
    if rigid_gap is not None:
        rigid = fast.solve(Impact(imp.params, speed)).cor
        assert res.cor == pytest.approx(rigid, abs=rigid_gap)


def test_stiff_light_barrel_is_never_silently_wrong() -> None:
    """m2 = 1 mg with b = 0: the damping rate c1/m2 = 5e9 /s makes the model stiff.

    Radau, BDF and LSODA agree (~17,000 Radau steps, a few seconds); the explicit kernel exhausts its
    2e6-step budget (~2 s) and must say so with SolverError, or else agree with them.
    """
    imp = Impact(CollisionParams.build(m2=1e-6, b=0.0), 1.0, 1e4)
    radau = solve_reference(imp, "Radau", 1e-10)
    check_physical(imp, radau)
    for method in ("BDF", "LSODA"):
        other = solve_reference(imp, method, 1e-10)
        assert other.cor == pytest.approx(radau.cor, abs=1e-8)
        assert other.contact_time_s == pytest.approx(radau.contact_time_s, rel=1e-6)
    try:
        res = fast.solve(imp)
    except SolverError as exc:
        assert "step budget" in str(exc)
    else:
        assert res.cor == pytest.approx(radau.cor, abs=1e-8)


def test_light_undamped_barrel_is_knocked_away() -> None:
    """m2 << m1 with c2 = 0 behaves as a free light mass: COR -> -(m1 - m2)/(m1 + m2)."""
    params = CollisionParams.build(m2=1e-4, c1=0.0, c2=0.0)
    res = fast.solve(Impact(params, 1.0, 100.0))
    check_physical(Impact(params, 1.0, 100.0), res)
    # the first contact knocks the barrel away as a free light mass would (ball forward at
    # (m1 - m2)/(m1 + m2) v0); the undamped spring brings it back, so the ball is hit again and
    # leaves backwards in the end, energy conserved (check_physical)
    assert res.contacts >= 2
    assert 0.0 < res.cor <= 1.0


@pytest.mark.parametrize("body_mass", [1e3, 1e6])
@pytest.mark.parametrize("hoop", [None, 1250.0])
def test_heavy_bat_body_approaches_clamped_base(
    paper_params: CollisionParams, body_mass: float, hoop: float | None
) -> None:
    """A free body of mass M -> infinity is a clamp: COR falls by about (1 + e) m1/M (recoil)."""
    clamped = fast.solve(Impact(paper_params, 60.8, hoop), 1e-12).cor
    free = fast.solve(Impact(paper_params, 60.8, hoop, body_mass=body_mass), 1e-12).cor
    shift = (clamped - free) * body_mass / paper_params.m1
    assert 1.0 < shift < 3.0


# --- convergence ---------------------------------------------------------------------------------

Solver = Callable[[Impact, float], CollisionResult]
CONVERGENCE_SOLVERS: dict[str, Solver] = {
    "fast": lambda imp, rtol: fast.solve(imp, rtol),
    "DOP853": lambda imp, rtol: solve_reference(imp, "DOP853", rtol),
    "RK45": lambda imp, rtol: solve_reference(imp, "RK45", rtol),
    "LSODA": lambda imp, rtol: solve_reference(imp, "LSODA", rtol),
}
RTOLS = np.array([1e-4, 1e-6, 1e-8, 1e-10])


@pytest.mark.parametrize(("speed", "hoop"), [(60.8, 1250.0), (26.8, None), (1.0, 1e4), (0.01, 300.0)])
@pytest.mark.parametrize("name", sorted(CONVERGENCE_SOLVERS))
def test_error_shrinks_as_tolerance_tightens(
    paper_params: CollisionParams, name: str, speed: float, hoop: float | None
) -> None:
    """|COR - COR_ref| against two agreeing tight solves: below 100 rtol, falling about as rtol.

    The reference is fast and scipy DOP853 at rtol 1e-13, which must agree to 1e-11 themselves.
    """
    imp = Impact(paper_params, speed, hoop)
    tight_fast = fast.solve(imp, 1e-13).cor
    tight_ref = solve_reference(imp, "DOP853", 1e-13).cor
    assert tight_fast == pytest.approx(tight_ref, abs=1e-11)
    errors = np.array([abs(CONVERGENCE_SOLVERS[name](imp, float(r)).cor - tight_ref) for r in RTOLS])
    errors = np.maximum(errors, 1e-14)
    assert np.all(errors <= 100.0 * RTOLS)
    assert errors[-1] <= 1e-8
    assert errors[-1] < errors[0] / 100.0
    slope = np.polyfit(np.log10(RTOLS), np.log10(errors), 1)[0]  # tolerance proportionality
    assert slope > 0.45


def test_more_work_at_tighter_tolerance(paper_params: CollisionParams) -> None:
    """nfev grows as rtol tightens, for both solvers (they do not ignore the tolerance)."""
    imp = Impact(paper_params, 60.8, 1250.0)
    for solver in (fast.solve, lambda i, r: solve_reference(i, "DOP853", r)):
        nfev = [solver(imp, float(r)).nfev for r in RTOLS]
        assert all(lo < hi for lo, hi in itertools.pairwise(nfev))


# --- known failures (bugs and limits found by this suite) ----------------------------------------


def first_separation(
    params: CollisionParams, speed: float, hoop: float, max_step: float
) -> tuple[float, float]:
    """Independent oracle: (COR, contact time) at the first zero of F, by scipy with a short max_step.

    Own right-hand side and event, so neither the code's equations nor its kernel are involved.
    """
    m1, k1, c1, a, b, m2, c2 = params.m1, params.k1, params.c1, params.a, params.b, params.m2, params.c2
    k2 = m2 * (2.0 * math.pi * hoop) ** 2

    def rhs(t: float, y: np.ndarray) -> list[float]:
        d, dd = y[0] - y[2], y[1] - y[3]
        f = k1 * d * abs(d) ** a + c1 * dd * abs(d) ** b
        return [y[1], -f / m1, y[3], (f - k2 * y[2] - c2 * y[3]) / m2]

    def g(t: float, y: np.ndarray) -> float:
        d = y[0] - y[2]
        return (k1 * d * abs(d) ** (a - b) if d != 0.0 else 0.0) + c1 * (y[1] - y[3])

    g.terminal = True  # type: ignore[attr-defined]
    g.direction = -1  # type: ignore[attr-defined]
    length = params.compression_scale(speed)
    atol = 1e-12 * np.array([length, speed, length, speed])
    sol = solve_ivp(
        rhs, (0.0, 1.0), [0.0, speed, 0.0, 0.0], "DOP853", rtol=1e-12, atol=atol, events=g, max_step=max_step
    )
    return -float(sol.y_events[0][0][1]) / speed, float(sol.t_events[0][0])


GRAZING_HOOPS = np.arange(150.0, 156.8, 0.25)  # paper's constants at 60.8 m/s


@pytest.mark.parametrize("name", ["fast", "reference"])
def test_grazing_separation_is_not_skipped(paper_params: CollisionParams, name: str) -> None:
    """Near 155 Hz F dips below zero for ~40 us at 0.56 ms: a brief separation, then contact again.

    The first zero of F must still be found (the independent oracle locates it; the solvers must
    report more than one contact there), and the COR is the ball's speed after the last contact:
    ~+0.26, continuous in the hoop frequency (it used to be the -0.40 of the first zero, jumping to
    +0.27 at ~156.9 Hz). tests/physics/test_recontact.py checks the COR against a clipped-force solve.
    """
    solver = CONVERGENCE_SOLVERS["fast" if name == "fast" else "DOP853"]
    missed = []
    for hoop in GRAZING_HOOPS:
        cor_first, _ = first_separation(paper_params, 60.8, float(hoop), max_step=1e-6)
        assert cor_first < 0.0  # the ball is still moving into the barrel at the first zero of F
        res = solver(Impact(paper_params, 60.8, float(hoop)), 1e-10)
        if res.contacts < 2 or not 0.2 < res.cor < 0.3:
            missed.append((float(hoop), res.cor, res.contacts))
    assert not missed, f"brief separation missed at (hoop, COR, contacts): {missed}"


def test_light_barrel_contact_outlasting_time_limit() -> None:
    """m2 = 1 mg at 100 Hz, c2 = 0: Radau handles the stiffness; the contact lasts 1.904 s."""
    params = CollisionParams.build(m2=1e-6, c2=0.0)
    res = solve_reference(Impact(params, 1.0, 100.0), "Radau", 1e-8)
    assert res.contact_time_s == pytest.approx(math.pi * math.sqrt(params.m1 / params.k2(100.0)), rel=0.01)
    assert res.cor == pytest.approx(1.0, abs=1e-4)


def test_reference_survives_a_flat_contact_end_event() -> None:
    """Undamped ball, a = 1, b = 0: g = k1 d|d| has a zero of order 2 in d at separation.

    The fast solver returns COR = 1 here; the reference must too (or raise SolverError).
    """
    params = CollisionParams.build(k1=2e4, a=1.0, b=0.0, c1=0.0)
    assert fast.solve(Impact(params, 0.01), 1e-10).cor == pytest.approx(1.0, abs=1e-8)
    try:
        res = solve_reference(Impact(params, 0.01), "DOP853", 1e-10)
    except SolverError:
        return  # refusing with the project's own error is acceptable
    assert res.cor == pytest.approx(1.0, abs=1e-8)


FIRST_STEP_CASES = {
    # rigid, undamped: the exact COR is 1
    "rigid-undamped": (
        CollisionParams(m1=1.0, k1=22026.465794806718, a=0.6495, b=0.0, c1=0.0),
        0.01,
        None,
        False,
    ),
    # flexible, barrel damping only, with the energy quadratures in the state
    "flexible-energy": (
        CollisionParams(c1=0.0, a=0.8232222863533034, b=0.0, m2=1.0, c2=1.0),
        1.0,
        233.031,
        True,
    ),
}


@pytest.mark.parametrize("case", sorted(FIRST_STEP_CASES))
def test_reference_converges_in_a_non_smooth_corner(case: str) -> None:
    """c1 = 0, b = 0, fractional a: scipy's error must be <= 100 rtol at rtol 1e-8 and 1e-10.

    The truth is fast and scipy at rtol 1e-13, agreeing to 1e-10 (and 1 exactly for the rigid
    case). With first_step = 1e-4 * imp.time_scale() scipy meets the bound.
    """
    params, speed, hoop, energy = FIRST_STEP_CASES[case]
    imp = Impact(params, speed, hoop)
    truth = fast.solve(imp, 1e-13).cor
    assert solve_reference(imp, "DOP853", 1e-13).cor == pytest.approx(truth, abs=1e-10)
    for rtol in (1e-8, 1e-10):
        res = solve_reference(imp, "DOP853", rtol, energy=energy)
        assert res.cor == pytest.approx(truth, abs=100.0 * rtol)
        if energy:
            assert abs(res.energy["residual"]) <= 100.0 * rtol * res.energy["inbound_kinetic"]
