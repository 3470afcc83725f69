"""The contact's body in Taylor series steps (`_kernel_model.series`, `_dop853._series_contact`),
the efficiency curve's path, against what it did not make: the reference formulation's right-hand
side (`equations`), scipy's solve_ivp from the same state, the DOP853 kernel over random impacts,
and a polynomial whose minimum is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, note, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from rig.core.errors import ParameterError
from rig.physics import _dop853, _interpreted, _kernel_model, curve, equations, fast
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from tests.physics.test_kernel_model import impacts, states, units

ORDER = fast.SERIES_ORDER
overlaps = st.floats(0.05, 2.0)  # d = x1 - x2 in compression scales: in contact


def in_contact(imp: Impact, unit: list[float], overlap: float) -> tuple[np.ndarray, np.ndarray]:
    """(reduced, kernel) states of `imp` with the ball `overlap` compression scales into the barrel."""
    reduced, full = states(imp, unit)
    shift = overlap * imp.params.compression_scale(imp.speed) - (full[0] - full[2])
    reduced[0] += shift
    full[0] += shift
    return reduced, full


def expand(imp: Impact, y: np.ndarray, order: int = ORDER) -> tuple[np.ndarray, np.ndarray]:
    """The series' coefficients (S, aux) at y."""
    S = np.zeros((6, order + 1))
    aux = np.zeros((7, order + 1))
    assert _kernel_model.series(y, fast.kernel_params(imp), order, S, aux)
    return S, aux


def at(S: np.ndarray, tau: float) -> np.ndarray:
    """Each state's polynomial at tau."""
    return np.array([np.polynomial.polynomial.polyval(tau, row) for row in S])


@given(imp=impacts, unit=units, overlap=overlaps)
def test_the_series_first_terms_are_the_reference_right_hand_side(
    imp: Impact, unit: list[float], overlap: float
) -> None:
    """The order-1 coefficients are the state's rates, as `equations` states the model."""
    reduced, full = in_contact(imp, unit, overlap)
    S, aux = expand(imp, full)
    n = imp.n_states
    rates = np.array(equations.make_rhs(imp)(0.0, reduced))
    size = np.abs(rates) + np.abs(imp.scales()) / imp.time_scale()
    assert np.all(np.abs(S[:n, 1] - rates) <= 1e-12 * size)
    d, dd = equations.relative_motion(imp, reduced)
    g = equations.separation_function(d, dd, imp.params)
    assert aux[_kernel_model._G, 0] == pytest.approx(g, rel=1e-12, abs=1e-12 * abs(imp.params.c1 * dd))


def test_a_state_out_of_contact_has_no_series() -> None:
    """d <= 0: the force's powers branch there; nothing is made and the caller goes on without."""
    imp = Impact(DEFAULT_PARAMS, 30.0, 1250.0)
    S = np.full((6, ORDER + 1), 7.0)
    aux = np.zeros((7, ORDER + 1))
    for d in (0.0, -1e-4):
        assert not _kernel_model.series(
            np.array([d, 30.0, 0, 0, 0, 0]), fast.kernel_params(imp), ORDER, S, aux
        )
    assert np.all(S == 7.0)


def reference_flow(imp: Impact, reduced: np.ndarray, tau: float) -> np.ndarray:
    """The reference's state after tau, by scipy's DOP853 at its tightest."""
    sol = solve_ivp(
        equations.make_rhs(imp), (0.0, tau), reduced, "DOP853", rtol=1e-13, atol=1e-15 * imp.scales()
    )
    assert sol.success
    return sol.y[:, -1]


@settings(max_examples=60, deadline=None)
@given(imp=impacts, unit=units, overlap=overlaps)
def test_one_series_step_is_the_reference_flow(imp: Impact, unit: list[float], overlap: float) -> None:
    """The step the kernel takes from a state in contact lands where solve_ivp does, and the error at a
    fixed time falls as the order grows (convergence under refinement)."""
    reduced, full = in_contact(imp, unit, overlap)
    n = imp.n_states
    scales = np.tile([imp.params.compression_scale(imp.speed), imp.speed], 3)
    rtol = 1e-10
    S, aux = expand(imp, full)
    h = _dop853._series_step(S, aux, full, rtol, rtol * scales, math.inf, n, ORDER)
    h = min(h, 2.0 * imp.time_scale())
    assume(np.polynomial.polynomial.polyval(h, aux[_kernel_model._D]) > 0.0)  # still in contact
    exact = reference_flow(imp, reduced, h)
    size = np.maximum(np.abs(full[:n]), scales[:n])
    assert np.all(np.abs(at(S, h)[:n] - exact) <= 1e-8 * size)
    # at half that step, each doubling of the order gains (until rounding is all that is left)
    errors = []
    half = reference_flow(imp, reduced, 0.5 * h)
    for order in (4, 8, ORDER):
        errors.append(float(np.max(np.abs(at(expand(imp, full, order)[0], 0.5 * h)[:n] - half) / size)))
    floor = 1e-12
    assert errors[2] <= max(errors[1], floor) and errors[1] <= max(errors[0], floor)


def test_a_linear_ball_on_a_wall_is_its_closed_form() -> None:
    """a = b = 0 on a rigid clamped wall: m d'' = -k d - c d', d(0) = 0, d'(0) = v0, so
    d = (v0/wd) e^(-s t) sin(wd t). Expanded at t0 (a state at d = 0 has no series): the first
    coefficients are the closed form's d^(j)(t0)/j!, and the polynomial at the kernel's step from
    there is the closed form's state to the tolerance.

    Only the first few coefficients are compared one by one: the powers of d are made through log d,
    whose branch point at t = 0 lies t0 away, so rounding in a coefficient of order j grows about as
    (1 / (wd t0))^j, here 10^j; the step rule reads those coefficients as they are, so the step is
    shorter, never less accurate (the second assertion)."""
    params = CollisionParams.build(k1=1e6, c1=300.0, a=0.0, b=0.0)
    v0 = 2.0
    imp = Impact(params, v0)
    m, k, c = params.m1, params.k1, params.c1
    s = c / (2.0 * m)
    wd = math.sqrt(k / m - s * s)
    lam = complex(-s, wd)
    t0 = 0.1 / wd

    def closed(t: float, j: int = 0) -> float:
        """d^(j)(t) / j!: the imaginary part of (v0/wd) lam^j e^(lam t) / j!."""
        return (v0 / wd * lam**j * np.exp(lam * t)).imag / math.factorial(j)

    y = np.array([closed(t0), closed(t0, 1), 0.0, 0.0, 0.0, 0.0])
    S, aux = expand(imp, y)
    exact = np.array([closed(t0, j) for j in range(7)])
    assert S[0, :7] == pytest.approx(exact, rel=1e-9)
    assert S[2].tolist() == [0.0] * (ORDER + 1)  # the clamped wall does not move
    rtol = 1e-10
    scales = np.tile([params.compression_scale(v0), v0], 3)
    h = _dop853._series_step(S, aux, y, rtol, rtol * scales, math.inf, 2, ORDER)
    assert h > 0.5 * t0
    assert at(S, h)[0] == pytest.approx(closed(t0 + h), abs=10 * rtol * scales[0])
    assert at(S, h)[1] == pytest.approx(closed(t0 + h, 1), abs=10 * rtol * v0)


def test_a_dip_between_two_positive_ends_is_found() -> None:
    """g = d on a clamped wall whose ball moves as d = (x - 0.3)^2 - 0.01 over the step's fractions x
    (k1 = 1, c1 = 0, a = b): positive at both ends, below zero between 0.2 and 0.4. The step's g
    polynomial is not proved positive (its Bernstein coefficients), so it is read at SERIES_SAMPLES
    points: the first at or below zero bounds the end, and g of the states falls through zero at 0.2."""
    p = fast.kernel_params(Impact(CollisionParams.build(k1=1.0, c1=0.0, a=0.5, b=0.5), 1.0))
    h = 2.0  # the step: the searches run over its fractions x = t / h
    S = np.zeros((6, 3))
    S[0] = [0.08, -0.6 / h, 1.0 / h**2]
    aux = np.zeros((7, 3))
    aux[_kernel_model._G] = S[0]  # g = d here
    y, unused, tmp = np.zeros(6), np.zeros((7, 6)), np.zeros(6)
    assert not _dop853._g_stays_up(aux, 2, h)
    x = _dop853._series_first_down(aux, 2, h)
    assert 0.2 <= x <= 0.2 + 1.0 / _dop853.SERIES_SAMPLES
    g = _dop853._g_at(x, y, unused, S, h, 2, p, tmp)
    assert g <= 0.0
    root = _dop853._crossing(y, unused, S, h, 2, p, tmp, 0.08, x, g)
    assert root == pytest.approx(0.2, rel=1e-12)
    aux[_kernel_model._G, 0] = 0.1  # the least value 0.01 > 0: no sample at or below zero
    assert _dop853._series_first_down(aux, 2, h) == 2.0
    assert not _dop853._g_stays_up(aux, 2, h)  # Bernstein coefficients 0.1, -0.2, 0.5: not proved
    aux[_kernel_model._G] = [1.0, -0.3 / h, 0.2 / h**2]  # 1, 0.85, 0.9: above zero, proved
    assert _dop853._g_stays_up(aux, 2, h)


@settings(max_examples=60, deadline=None)
@given(imp=impacts, rtol=st.sampled_from([1e-8, 1e-10]))
# an outside review's case: DOP853, resuming after a hand-back, stepped across d = 0 on its second
# step (the cap then held only for its first) and ended the contact 400 tolerances off
@example(
    imp=Impact(
        CollisionParams(
            m1=0.474624445538412,
            k1=1058802904.6148578,
            c1=10107.543210291089,
            a=0.10830078222623374,
            b=0.23294144337478917,
            m2=0.3872628452086158,
            c2=0.0,
        ),
        31.954592283398664,
        None,
    ),
    rtol=1e-8,
)
def test_series_solves_are_as_accurate_as_dop853_over_random_impacts(imp: Impact, rtol: float) -> None:
    """Over random constants, speeds, barrels and bases, the first contact (the kernel's part) ends
    where the DOP853 kernel at rtol 1e-13 says, no further off than DOP853 at the same tolerance
    (or 100 tolerances): the COR; the time of the end to what locating g = 0 to 100 tolerances of
    its scale allows (an over-damped ball's g crosses zero slowly, and its end time is ill-
    conditioned: DOP853's own error there depends on where its steps fall); the state at the end
    to 100 tolerances plus its motion over that time. Later contacts are the reference's
    (`continue_contacts`), which can amplify the first one's error many times over."""
    module = fast.compiled()
    cor, tc, _, status, state = fast._solve_one(imp, rtol, module, fast.MAX_STEPS)
    assume(status in (module.STATUS_OK, module.STATUS_FOLLOW))
    s_cor, s_tc, _, s_status, s_state = fast._solve_one(imp, rtol, module, fast.MAX_STEPS, ORDER)
    assert s_status in (module.STATUS_OK, module.STATUS_FOLLOW), "the series path failed where DOP853 did not"
    r_cor, r_tc, _, r_status, r_state = fast._solve_one(imp, 1e-13, module, fast.MAX_STEPS)
    assume(r_status in (module.STATUS_OK, module.STATUS_FOLLOW))
    note(f"COR errors: DOP853 {abs(cor - r_cor):.3g}, series {abs(s_cor - r_cor):.3g}")
    assert abs(s_cor - r_cor) <= max(100.0 * rtol, 3.0 * abs(cor - r_cor))
    p = fast.kernel_params(imp)
    rates = np.zeros(6)
    _kernel_model.rhs(r_state, p, rates)
    g_rate = abs(_kernel_model.gdot(r_state, rates, p))
    located = 100.0 * rtol * equations.contact_scale(imp) / g_rate if g_rate > 0.0 else r_tc
    dt = max(100.0 * rtol * r_tc, 3.0 * abs(tc - r_tc), min(located, r_tc))
    note(f"end time errors: DOP853 {abs(tc - r_tc):.3g}, series {abs(s_tc - r_tc):.3g}, allowed {dt:.3g}")
    assert abs(s_tc - r_tc) <= dt
    size = np.tile([imp.params.compression_scale(imp.speed), imp.speed], 3) + np.abs(r_state)
    allowed = np.maximum(100.0 * rtol * size + np.abs(rates) * dt, 3.0 * np.abs(state - r_state))
    assert np.all(np.abs(s_state - r_state) <= allowed)


@pytest.mark.parametrize("hoop", [300.0, 1250.0, 5000.0, 19000.0])
def test_series_solves_agree_with_the_tight_reference_on_the_papers_ball(hoop: float) -> None:
    imp = Impact(DEFAULT_PARAMS, 60.8, hoop)
    res = fast.solve_series(imp, 1e-10)
    ref = fast.solve(imp, 1e-13)
    assert res.cor == pytest.approx(ref.cor, abs=3e-10)
    assert res.contact_time_s == pytest.approx(ref.contact_time_s, rel=3e-10)
    assert res.method.startswith("rig-DOP853+series")


def test_the_series_takes_fewer_steps_than_dop853_on_a_stiff_barrel() -> None:
    """At 19 kHz DOP853 takes about five steps a barrel period; the series step over several."""
    imp = Impact(DEFAULT_PARAMS, 60.8, 19000.0)
    p = fast.kernel_params(imp)
    scale = DEFAULT_PARAMS.compression_scale(60.8)
    counts = []
    for series in (0, ORDER):
        out = _dop853.solve_one(
            p, 60.8, scale, 3e-8, 4, fast._time_limit(imp), fast.MAX_STEPS, np.zeros(6), series
        )
        counts.append(out[3])
    assert counts[1] < 0.6 * counts[0]


def test_the_interpreted_kernel_runs_the_same_series() -> None:
    """The interpreted kernel (the same source, no numba) gives the compiled kernel's numbers."""
    imp = Impact(DEFAULT_PARAMS, 60.8, 4000.0)
    compiled = fast.solve_general(imp, 1e-9, fast.compiled(), ORDER)
    interpreted = fast.solve_general(imp, 1e-9, _interpreted.load(), ORDER)
    assert interpreted.cor == pytest.approx(compiled.cor, rel=1e-13)
    assert interpreted.contact_time_s == pytest.approx(compiled.contact_time_s, rel=1e-13)


def test_the_curve_takes_the_series_path_and_dop853_on_request() -> None:
    hoops = np.array([800.0, 1250.0, 9000.0])
    with_series, _ = curve.cor_grid(DEFAULT_PARAMS, 60.8, hoops, rtol=1e-10)
    without, _ = curve.cor_grid(DEFAULT_PARAMS, 60.8, hoops, rtol=1e-10, series=0)
    single = [fast.solve_series(Impact(DEFAULT_PARAMS, 60.8, float(f)), 1e-10).cor for f in hoops]
    assert with_series.tolist() == single
    assert without.tolist() == [fast.solve(Impact(DEFAULT_PARAMS, 60.8, float(f)), 1e-10).cor for f in hoops]
    assert np.max(np.abs(with_series - without)) < 1e-8


def test_the_series_are_used_only_where_the_contact_ends_clear_of_d_0() -> None:
    """g falls to zero at d ~ (c1 v0 / k1)^(1 / (1+a-b)): the paper's ball ends 0.67 compression
    scales clear of d = 0, an undamped ball at d = 0 and a nearly undamped one ~1e-5 scales away;
    those two take DOP853 steps throughout, to the last bit."""
    scale = DEFAULT_PARAMS.compression_scale(60.8)
    assert _dop853._series_ends_clear(fast.kernel_params(Impact(DEFAULT_PARAMS, 60.8, 1250.0)), 60.8, scale)
    for c1 in (0.0, 0.05):
        imp = Impact(CollisionParams.build(c1=c1), 60.8, 1250.0)
        assert not _dop853._series_ends_clear(fast.kernel_params(imp), 60.8, scale)
        series, dop = fast.solve_series(imp, 1e-10), fast.solve(imp, 1e-10)
        assert (series.cor, series.contact_time_s, series.nfev) == (dop.cor, dop.contact_time_s, dop.nfev)


@pytest.mark.parametrize("order", [1, 2, 3, 18, 66, -1, 16.0])
def test_a_series_order_outside_4_to_17_is_refused(order: object) -> None:
    """Fewer terms step no further than DOP853 (order 1 would divide by zero), more outgrow the
    dip search's samples and the reciprocals' table: one clear line, naming the parameter."""
    imp = Impact(DEFAULT_PARAMS, 60.8, 1250.0)
    with pytest.raises(ParameterError, match="series"):
        fast.solve_series(imp, 1e-8, order)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="series"):
        curve.cor_grid(DEFAULT_PARAMS, 60.8, np.array([1250.0]), series=order)  # type: ignore[arg-type]


@settings(max_examples=200, deadline=None)
@given(coefficients=st.lists(st.floats(-1.0, 1.0), min_size=2, max_size=17), h=st.floats(0.1, 3.0))
def test_a_polynomial_proved_positive_is_positive(coefficients: list[float], h: float) -> None:
    """Whatever the coefficients, where the Bernstein test says g's polynomial stays above zero over
    the step, it does at 2001 points (the convex-hull property, checked by evaluation)."""
    degree = len(coefficients) - 1
    aux = np.zeros((7, degree + 1))
    aux[_kernel_model._G] = coefficients
    if _dop853._g_stays_up(aux, degree, h):
        values = np.polynomial.polynomial.polyval(np.linspace(0.0, h, 2001), coefficients)
        assert np.all(values > 0.0)
