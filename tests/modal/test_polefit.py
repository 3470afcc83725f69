"""The pole fit's pieces against references written here: the exact Jacobian of the projected residual
against central differences of a residual computed by numpy's lstsq, the batched solver against closed
forms, and a batch of fits against the same fits alone.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from rig.modal import levmar
from rig.modal.polefit import Problem, fit_many, fit_poles
from rig.modal.varpro import Evaluation, PoleModel

DT = 1.0 / 51200.0
TAU = 0.1 / math.log(100.0)


def _band(f0: float, width_hz: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """s at k bins across +-width/2 around f0, as the FRF samples them (exponential window), and x."""
    f = np.linspace(f0 - width_hz / 2, f0 + width_hz / 2, k)
    s = 2j * np.pi * f + 1.0 / TAU
    w0 = 2 * np.pi * f0
    return s, (s.imag - s.imag.mean()) / w0


def _reference_residual(
    theta: np.ndarray, y: np.ndarray, s: np.ndarray, x: np.ndarray, w0: float
) -> np.ndarray:
    """The variable-projection residual written out: basis column by column, lstsq, A c - y."""
    cols = []
    for i in range(theta.size // 2):
        p = complex(-theta[2 * i], theta[2 * i + 1]) * w0
        for pole in (p, np.conj(p)):  # R g(p) + conj(R) g(conj p), R = a + j b: a (g1 + g2) + b j (g1 - g2)
            cols.append(1.0 / -np.expm1((pole - s) * DT))
        cols[-2:] = [cols[-2] + cols[-1], 1j * (cols[-2] - cols[-1])]
    cols += [np.ones_like(x), 1j * np.ones_like(x), x + 0j, 1j * x]
    a = np.stack(cols, axis=1)
    a = np.vstack([a.real, a.imag])
    c, *_ = np.linalg.lstsq(a, y, rcond=None)
    return (a @ c - y).T.ravel()


@settings(max_examples=60, deadline=None)
@given(
    f0=st.floats(150.0, 6000.0),
    window_s=st.floats(0.05, 2.0),
    n_poles=st.integers(1, 3),
    zetas=st.lists(st.floats(1e-3, 0.1), min_size=3, max_size=3),
    offsets=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    widths=st.floats(2.5, 5.0),
    seed=st.integers(0, 2**16),
)
def test_jacobian_matches_central_differences(
    f0: float,
    window_s: float,
    n_poles: int,
    zetas: list[float],
    offsets: list[float],
    widths: float,
    seed: int,
) -> None:
    """Golub-Pereyra's derivative against central differences (fourth order) of an independently
    written residual, over windows of 0.05-2 s, damping from 0.1 % to 10 %, one to three poles
    anywhere in a band of +-2.5-5 half-power bandwidths (at least +-4 bins, as the analysis fits)."""
    tau = window_s / math.log(100.0)
    bandwidth = 2 * max(zetas[:n_poles]) * f0 + 1.0 / (math.pi * tau)
    half = max(widths * bandwidth, 4.0 / window_s)
    k = 2 * math.ceil(half * window_s) + 1
    f = f0 + (np.arange(k) - k // 2) / window_s
    s = 2j * np.pi * f + 1.0 / tau
    w0 = 2 * np.pi * f0
    x = (s.imag - s.imag.mean()) / w0
    y = np.random.default_rng(seed).normal(size=(2 * k, 2))
    theta = np.empty(2 * n_poles)
    theta[0::2] = zetas[:n_poles]
    theta[1::2] = 1.0 + 0.8 * min(half, f0 / 2) / f0 * np.array(offsets[:n_poles])
    # two coinciding poles make two equal basis columns: the projection drops a dimension there and is
    # not differentiable (a draw of f0=150, 2 poles, equal damping and offsets found it); poles a
    # quarter bandwidth apart in frequency or in damping keep the basis of full rank
    for i, j in itertools.combinations(range(n_poles), 2):
        apart_f = abs(theta[2 * i + 1] - theta[2 * j + 1]) * f0 > 0.25 * bandwidth
        apart_z = abs(theta[2 * i] - theta[2 * j]) > 0.25 * max(theta[2 * i], theta[2 * j])
        assume(apart_f or apart_z)
    model = PoleModel(y[None], s[None], DT, x[None], np.array([w0]), np.ones((1, k), bool))
    ev = model.evaluate(theta[None], np.array([0]))
    np.testing.assert_allclose(ev.residuals[0], _reference_residual(theta, y, s, x, w0), atol=1e-9)
    jac = model.jacobian(ev)[0]
    fd = np.empty_like(jac)
    for i in range(theta.size):
        h = 1e-3 * theta[0::2].min()  # a small share of the poles' damping, the scale the residual varies on

        def at(step: float, i: int = i, h: float = h) -> np.ndarray:
            moved = theta.copy()
            moved[i] += step * h
            return _reference_residual(moved, y, s, x, w0)

        fd[:, i] = (8 * (at(1) - at(-1)) - (at(2) - at(-2))) / (12 * h)
    scale = np.max(np.abs(fd), axis=0)
    np.testing.assert_allclose(jac / scale, fd / scale, atol=1e-5)


def test_padded_rows_change_nothing() -> None:
    """A band padded with unused bins (to share a batch with a wider one) keeps its residual and Jacobian."""
    s, x = _band(2000.0, 200.0, 30)
    y = np.random.default_rng(1).normal(size=(60, 2))
    theta = np.array([[0.01, 1.001]])
    w0 = np.array([2 * np.pi * 2000.0])
    alone = PoleModel(y[None], s[None], DT, x[None], w0, np.ones((1, 30), bool))
    pad_s = np.concatenate([s, np.full(10, s[-1])])
    pad_y = np.zeros((80, 2))
    pad_y[:30], pad_y[40:70] = y[:30], y[30:]
    used = np.concatenate([np.ones(30, bool), np.zeros(10, bool)])
    padded = PoleModel(pad_y[None], pad_s[None], DT, np.concatenate([x, np.zeros(10)])[None], w0, used[None])
    a, b = alone.evaluate(theta, np.array([0])), padded.evaluate(theta, np.array([0]))
    rows = np.concatenate([np.arange(30), 40 + np.arange(30)])
    np.testing.assert_allclose(b.r[0][rows], a.r[0], atol=1e-12)
    np.testing.assert_allclose(b.r[0][30:40], 0.0, atol=1e-12)
    ja, jb = alone.jacobian(a)[0], padded.jacobian(b)[0]
    np.testing.assert_allclose(jb.reshape(2, 80, 2)[:, rows].reshape(-1, 2), ja, atol=1e-9)


class _Linear:
    """Linear least squares: the solver's answer has a closed form (numpy's lstsq)."""

    def __init__(self, a: np.ndarray, y: np.ndarray) -> None:
        self.a, self.y = a, y

    def fun(self, x: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        return np.einsum("bmn,bn->bm", self.a[rows], x) - self.y[rows], (rows, x)

    def jac(self, state: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        return self.a[state[0]]

    @staticmethod
    def subset(state: tuple[np.ndarray, np.ndarray], pick: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return state[0][pick], state[1][pick]


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**16), b=st.integers(1, 6), n=st.integers(1, 5))
def test_solver_finds_the_linear_least_squares_solution(seed: int, b: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    a, y = rng.normal(size=(b, 3 * n + 4, n)), rng.normal(size=(b, 3 * n + 4))
    prob = _Linear(a, y)
    big = np.full((b, n), 1e3)
    sol = levmar.solve(prob.fun, prob.jac, prob.subset, np.zeros((b, n)), -big, big, ftol=1e-14, xtol=1e-14)
    assert sol.success.all()
    for i in range(b):
        exact, *_ = np.linalg.lstsq(a[i], y[i], rcond=None)
        np.testing.assert_allclose(sol.x[i], exact, atol=1e-7)


def test_solver_stops_at_an_active_bound() -> None:
    """min (x - b)^2 over x <= 1: x = 1 for b = 2 (the bound), x = b = 0.5 inside."""
    a = np.ones((2, 1, 1))
    prob = _Linear(a, np.array([[2.0], [0.5]]))
    sol = levmar.solve(
        prob.fun, prob.jac, prob.subset, np.zeros((2, 1)), np.full((2, 1), -5.0), np.ones((2, 1))
    )
    np.testing.assert_allclose(sol.x[:, 0], [1.0, 0.5], atol=1e-8)
    assert sol.success.all()


def _mode_frf(
    f_hz: float, zeta: float, s: np.ndarray, residue: complex, noise: float, seed: int
) -> np.ndarray:
    """Two FRFs of one sampled mode plus a constant, with white noise: the model's own form."""
    wn = 2 * np.pi * f_hz
    p = complex(-zeta * wn, wn * math.sqrt(1 - zeta**2))
    g1 = 1.0 / -np.expm1((p - s) * DT)
    g2 = 1.0 / -np.expm1((np.conj(p) - s) * DT)
    rng = np.random.default_rng(seed)
    h = []
    for r in (residue, 0.7 * residue):
        clean = r * g1 + np.conj(r) * g2 + 0.01
        h.append(clean + noise * (rng.normal(size=s.size) + 1j * rng.normal(size=s.size)))
    return np.array(h)


def test_noise_free_mode_is_recovered_exactly() -> None:
    """The fitted pole of data made by the model itself is the true one (closed form: zero residual)."""
    f, zeta = 2137.3, 0.0071
    s, _ = _band(2140.0, 150.0, 25)
    h = _mode_frf(f, zeta, s, 3e-3 + 1e-3j, 0.0, 0)
    fit = fit_poles(h, s, DT, [complex(-0.01 * 2 * np.pi * 2140, 2 * np.pi * 2140)], 1.5, (0, 25))
    assert fit is not None
    assert fit.frequencies_hz[0] == pytest.approx(f, abs=1e-6)
    assert fit.damping_ratios[0] == pytest.approx(zeta, rel=1e-6)


def test_a_batch_gives_each_fit_what_it_gives_alone() -> None:
    """Bands of different widths and frequencies solved in one padded batch, against one at a time."""
    problems = []
    for i, (f, width, k) in enumerate([(480.0, 60.0, 9), (2100.0, 200.0, 31), (2400.0, 120.0, 17)]):
        s, _ = _band(f, width, k)
        h = _mode_frf(f + 3.0, 0.006, s, 2e-3 - 1e-3j, 2e-4, i)
        guess = complex(-0.01 * 2 * np.pi * f, 2 * np.pi * f)
        problems.append(Problem(h, s, (guess,), (i, i + k)))
    together = fit_many(problems, DT, 1.5)
    for p, fit in zip(problems, together, strict=True):
        alone = fit_poles(p.h, p.s, DT, p.guesses, 1.5, p.bins)
        assert fit is not None and alone is not None
        assert fit.frequencies_hz[0] == pytest.approx(alone.frequencies_hz[0], abs=1e-7)
        assert fit.u_frequency_hz[0] == pytest.approx(alone.u_frequency_hz[0], rel=1e-6)
        assert fit.cost == pytest.approx(alone.cost, rel=1e-9)
        assert fit.n_residuals == alone.n_residuals == 4 * p.s.size


def test_evaluation_subset_keeps_its_rows() -> None:
    s, x = _band(1000.0, 100.0, 20)
    y = np.random.default_rng(2).normal(size=(3, 40, 2))
    model = PoleModel(
        y, np.tile(s, (3, 1)), DT, np.tile(x, (3, 1)), np.full(3, 2 * np.pi * 1000.0), np.ones((3, 20), bool)
    )
    ev = model.evaluate(np.tile([0.01, 1.0], (3, 1)), np.arange(3))
    part = Evaluation.subset(ev, np.array([2]))
    np.testing.assert_allclose(model.jacobian(part)[0], model.jacobian(ev)[2])


def test_a_fit_of_bad_data_fails_alone() -> None:
    """Non-finite or all-zero FRFs in a batch: those fits fail (None), the others are as they are alone."""
    s, _ = _band(2100.0, 200.0, 31)
    good = _mode_frf(2103.0, 0.006, s, 2e-3 - 1e-3j, 2e-4, 0)
    nan = good.copy()
    nan[0, 5] = np.nan
    guess = (complex(-0.01 * 2 * np.pi * 2100, 2 * np.pi * 2100),)
    fits = fit_many([Problem(h, s, guess, (0, 31)) for h in (nan, good, np.zeros_like(good))], DT, 1.5)
    alone = fit_poles(good, s, DT, guess, 1.5, (0, 31))
    assert fits[0] is None
    assert fits[1] is not None and alone is not None
    assert fits[1].frequencies_hz[0] == pytest.approx(alone.frequencies_hz[0], abs=1e-7)
    assert fits[2] is None or np.isfinite(fits[2].cost)
