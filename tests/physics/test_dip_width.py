"""The kernel's search for a dip of g inside a step (`_dop853._minimum`) stops once its bracket is
`dip_width(rtol)` wide (sqrt(rtol), at most 1e-3 of the step), no longer at 1e-12. Its promise: a dip
deeper than max|g''| w^2 / 2 below zero (x in step fractions) is still found, and what the search
finds is what the search to 1e-12 finds. Checked against that search, on dense outputs of random
shape whose g has a minimum inside the step (g falling at its start and rising at its end), as in
the steps the kernel searches, with the largest |g''| measured on a fine grid."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from rig.physics import _interpreted

K = _interpreted.load()  # the kernel's source, run by the interpreter (the compiled one is the same)
C1 = 5000.0
GRID = np.linspace(0.0, 1.0, 4001)


def step_with(coefficients: list[float], start: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(y, F, p) of a step whose g is c1 v1(x): no spring (k1 = 0), a clamped flexible barrel at
    rest, the ball's speed on the dense output's 7 coefficients."""
    p = np.array([0.145, 0.0, C1, 0.65, 0.52, 0.09, 5.6e3, 0.0, 0.0, 0.0, 0.0])
    y = np.zeros(6)
    y[1] = start
    F = np.zeros((7, 6))
    F[:, 1] = coefficients
    return y, F, p


def g_on(y: np.ndarray, F: np.ndarray, p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """g on the dense output at the fractions x: the kernel's `_interpolate` and `_gfun`, the same
    operations in the same order over an array of x (numpy's vectorized power can differ from the
    scalar one in the last bit: checked below at a few points to 1e-13, far inside the margins)."""
    states = []
    for i in range(4):
        acc = np.zeros_like(x)
        for k in range(6, -1, -1):
            acc = (acc + F[k, i]) * (x if (6 - k) % 2 == 0 else 1.0 - x)
        states.append(y[i] + acc)
    d = states[0] - states[2]
    ad = np.abs(d)
    with np.errstate(all="ignore"):
        spring = np.where(ad > 0.0, p[1] * d * ad ** (p[3] - p[4]), 0.0)
    g = spring + p[2] * (states[1] - states[3])
    out = np.zeros(6)
    for j in (0, x.size // 3, x.size - 1):
        K._interpolate(y, F, float(x[j]), out, 4)
        assert float(g[j]) == pytest.approx(float(K._gfun(out, p)), rel=1e-13, abs=1e-300)
    return g


def test_the_width_is_the_square_root_of_the_tolerance_at_most_a_thousandth() -> None:
    assert K.dip_width(1e-10) == pytest.approx(1e-5)
    assert K.dip_width(3e-8) == pytest.approx(math.sqrt(3e-8))
    assert K.dip_width(1e-2) == 1e-3


@settings(max_examples=150, deadline=None)
@given(
    coefficients=st.lists(st.floats(-1.0, 1.0), min_size=7, max_size=7),
    depth=st.floats(-3.0, 3.0),
    rtol=st.sampled_from([1e-6, 3e-8, 1e-10, 1e-13]),
)
@example(coefficients=[0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0], depth=-1.0, rtol=1e-6)
@example(coefficients=[0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0], depth=1.0, rtol=1e-6)
def test_a_dip_deeper_than_the_widths_bound_is_found(
    coefficients: list[float], depth: float, rtol: float
) -> None:
    width = K.dip_width(rtol)
    # the dense output's form: x (F0 + (1 - x) (F1 + x (F2 + ...))); F0 = 0, F1 < 0 and F1 + F2 < 0:
    # g falls at the step's start and rises at its end, a minimum inside (the kernel's dips)
    c = [0.0, -0.05 - abs(coefficients[1]), -abs(coefficients[2]), *coefficients[3:]]
    y, F, p = step_with(c, 0.0)
    g = g_on(y, F, p, GRID)
    x = GRID[1] - GRID[0]
    assert g[1] < g[0] and g[-1] > g[-2]
    curvature = float(np.max(np.abs(np.diff(g, 2)))) / x**2
    bound = 0.5 * curvature * width**2
    # shift the speed so that g's least value on the grid sits `depth` bounds from zero
    y[1] = -(float(np.min(g)) + depth * max(bound, 1e-300)) / C1
    tmp = np.zeros(6)
    x_fine, g_fine = K._minimum(y, F, p, tmp, 1e-12)
    x_coarse, g_coarse = K._minimum(y, F, p, tmp, width)
    assert g_coarse >= g_fine or g_coarse <= 0.0  # the fine search goes on from where the coarse stopped
    if g_coarse <= 0.0:
        assert g_fine <= 0.0  # a point at or below zero: the fine search finds one too
    if g_fine < -1.5 * bound:
        assert g_coarse <= 0.0, (g_fine, g_coarse, bound)  # a dip deeper than the bound: found
    if g_coarse > 0.0:  # stopped short: within the bound of where the fine search ends
        assert g_coarse - g_fine <= 1.5 * bound + 1e-12 * float(np.ptp(g)), (g_coarse, g_fine, bound)
    assert 0.0 <= x_coarse <= 1.0 and 0.0 <= x_fine <= 1.0


@st.composite
def dense_steps(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A step's dense output in contact, scaled as the paper's ball at 60.8 m/s (d ~ 1e-2 m,
    d' ~ 10 m/s), with random exponents and damping: from far above g = 0 to grazing it."""
    a, b = draw(st.floats(0.0, 1.0)), draw(st.floats(0.0, 1.0))
    c1 = draw(st.sampled_from([0.0, 5000.0]) | st.floats(1.0, 1e5))
    p = np.array([0.145, 6e7, c1, a, b, 0.09, 5.6e3, 0.0, 0.0, 0.0, 0.0])
    y = np.zeros(6)
    y[0] = draw(st.floats(0.0, 0.05))
    y[2] = y[0] - draw(st.floats(-1e-3, 1.4e-2))  # d at the start
    y[1] = draw(st.floats(-60.0, 60.0))
    y[3] = y[1] - draw(st.floats(-60.0, 60.0))  # d' at the start
    scale = draw(st.sampled_from([1e-6, 1e-4, 1e-2, 1.0]))
    F = np.zeros((7, 6))
    for i, size in enumerate((1e-3, 10.0, 1e-3, 10.0)):
        F[:, i] = [scale * size * draw(st.floats(-1.0, 1.0)) for _ in range(7)]
    return y, F, p


@settings(max_examples=400, deadline=None)
@given(step=dense_steps())
def test_a_step_shown_clear_has_g_above_zero_all_over_its_dense_output(
    step: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """`_dense_clear` spares the dip search where g > 0 is shown over the whole step; it must
    never say so of a step whose g reaches zero: not on a fine grid, not where the search goes."""
    y, F, p = step
    if not K._dense_clear(y, F, p):
        return
    g = g_on(y, F, p, GRID)
    assert np.all(g > 0.0), float(np.min(g))
    assert K._minimum(y, F, p, np.zeros(6), 1e-12)[1] > 0.0


def test_the_paper_balls_dips_are_shown_clear_and_a_grazing_one_is_not() -> None:
    """The shortcut must pay where it is meant to: the wiggles of g far above zero that the paper's
    ball meets at 800-2000 Hz (read off the kernel's own dip steps) are shown clear; a step whose g
    grazes zero is left to the search."""
    from rig.physics import fast
    from rig.physics.equations import Impact
    from rig.physics.params import DEFAULT_PARAMS
    from rig.physics.reference import _time_limit

    seen: dict[float, list[bool]] = {}
    clear = K._dense_clear

    def watch(y: np.ndarray, F: np.ndarray, p: np.ndarray) -> bool:
        shown = bool(clear(y, F, p))
        seen.setdefault(hoop, []).append(shown)
        return shown

    K._dense_clear = watch
    try:
        for hoop in (800.0, 1250.0, 2000.0):
            imp = Impact(DEFAULT_PARAMS, 60.8, hoop)
            scale = DEFAULT_PARAMS.compression_scale(60.8)
            args = (fast.kernel_params(imp), 60.8, scale, 1e-8, imp.n_states, _time_limit(imp), 20_000)
            K.solve_one(*args, np.zeros(6), 0)
    finally:
        K._dense_clear = clear
    assert sorted(seen) == [800.0, 1250.0, 2000.0] and all(all(s) for s in seen.values()), seen
    # g = c1 v1 on the dense output v1 = y1 - x (1 - x), least at x = 1/2: grazing zero from above
    # or below is left to the search; clear by far (the bound, y1 - 1, above zero) is shown
    for least, shown in ((1e-9, False), (-1e-9, False), (1.25, True)):
        y, F, p = step_with([0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.25 + least)
        y[0] = 0.01  # d > 0
        assert bool(K._dense_clear(y, F, p)) is shown, least
