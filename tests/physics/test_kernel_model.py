"""The kernel's model has one definition (`_kernel_model`), which the compiled and the interpreted
kernel both run, and it gives the numbers of the reference's own formulation (`equations`), kept
apart on purpose, over random constants and states: the two cannot drift apart unseen."""

from __future__ import annotations

import importlib.util
import itertools
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from rig.physics import _dop853, _interpreted, _jit, _kernel_model, equations, fast
from rig.physics.equations import Impact
from rig.physics.params import CollisionParams

# the kernel's name for each model function
SHARED = {
    "_rhs": "rhs",
    "_rhs_free": "rhs_free",
    "_gfun": "gfun",
    "_gdot": "gdot",
    "_g_and_rate": "g_and_rate",
    "_damping_rate": "damping_rate",
    "g_cannot_rise": "g_cannot_rise",
    "_force_escape_time": "force_escape_time",
    "_series": "series",
    "_series_damped": "series_damped",
}


@pytest.mark.parametrize(("kernel_name", "model_name"), sorted(SHARED.items()))
def test_both_kernels_run_the_models_one_definition_compiled_inline(
    kernel_name: str, model_name: str
) -> None:
    function = getattr(_kernel_model, model_name)
    compiled = getattr(_dop853, kernel_name)
    assert getattr(_interpreted.load(), kernel_name) is function
    assert compiled.py_func is function
    assert compiled.targetoptions["inline"] == "always"  # no call overhead inside the loops


def test_the_model_text_is_pinned_where_numbas_cache_sees_it(tmp_path: Path) -> None:
    """numba keys the compiled kernel's cache on _dop853.py's text: an edit of the model that is not
    pinned there is refused, with the digest to pin."""
    assert _jit.source_digest(_kernel_model) == _dop853.MODEL_DIGEST
    source = Path(str(_kernel_model.__file__)).read_text(encoding="utf-8")
    edited = tmp_path / "edited_model.py"
    edited.write_text(
        source.replace("out[1] = -f / p[0]", "out[1] = -f / p[0] * 1.0000001"), encoding="utf-8"
    )
    spec = importlib.util.spec_from_file_location("edited_model", edited)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    digest = _jit.source_digest(module)
    assert digest != _dop853.MODEL_DIGEST
    with pytest.raises(ImportError, match=digest):
        _jit.check_digest(module, _dop853.MODEL_DIGEST, "_dop853.py")


params = st.builds(
    CollisionParams.build,
    m1=st.floats(0.05, 0.5),
    k1=st.floats(4.0, 10.0).map(lambda e: 10.0**e),
    c1=st.just(0.0) | st.floats(1.0, 1e5),
    a=st.floats(0.0, 1.0),
    b=st.floats(0.0, 1.0),
    m2=st.floats(1e-3, 1.0),
    c2=st.just(0.0) | st.floats(0.0, 1e4),
)
impacts = st.builds(
    Impact,
    params,
    st.floats(1.0, 100.0),
    st.none() | st.floats(50.0, 20000.0),
    st.none() | st.floats(0.05, 5.0),
)
flexible = impacts.filter(lambda imp: not imp.rigid)
units = st.lists(st.floats(-2.0, 2.0), min_size=6, max_size=6)  # state in compression scales and v0


def states(imp: Impact, unit: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """(the reference's reduced state, the kernel's 6-state) for one state given in units of the scales."""
    reduced = np.array(unit[: imp.n_states]) * imp.scales()
    full = np.zeros(6)
    full[: imp.n_states] = reduced
    if imp.rigid and imp.body_mass is not None:
        full[4:6] = reduced[2:4]  # the kernel moves its third body with the rigid barrel
    return reduced, full


@given(imp=impacts, unit=units, free=st.booleans())
def test_the_right_hand_sides_are_the_references(imp: Impact, unit: list[float], free: bool) -> None:
    """In contact, and in free flight (flexible barrels: the kernel's free flights are theirs only)."""
    free = free and not imp.rigid
    reduced, full = states(imp, unit)
    out = np.zeros(6)
    (_kernel_model.rhs_free if free else _kernel_model.rhs)(full, fast.kernel_params(imp), out)
    n = imp.n_states
    assert out[:n].tolist() == equations.make_rhs(imp, free=free)(0.0, reduced)
    if imp.body_mass is None:
        assert out[n:].tolist() == [0.0] * (6 - n)  # the clamped base stays at rest
    elif imp.rigid:
        assert out[4:].tolist() == out[2:4].tolist()


@given(imp=impacts, unit=units)
def test_g_its_rate_and_the_damping_rate_are_the_references(imp: Impact, unit: list[float]) -> None:
    reduced, full = states(imp, unit)
    p = fast.kernel_params(imp)
    d, dd = equations.relative_motion(imp, reduced)
    assert _kernel_model.gfun(full, p) == equations.separation_function(d, dd, imp.params)
    assert _kernel_model.damping_rate(full, p) == equations.damping_rate(imp, reduced)
    # g' along the reference's right-hand side: a central difference of its separation function
    length = imp.params.compression_scale(imp.speed)
    if abs(d) > 1e-3 * length:  # |d|^(a-b) is not smooth at d = 0
        f = np.zeros(6)
        _kernel_model.rhs(full, p, f)
        slope = np.array(equations.make_rhs(imp)(0.0, reduced))
        h = 1e-7 * imp.time_scale()
        ahead = equations.relative_motion(imp, reduced + h * slope)
        behind = equations.relative_motion(imp, reduced - h * slope)
        params = imp.params
        diff = (
            equations.separation_function(*ahead, params) - equations.separation_function(*behind, params)
        ) / (2.0 * h)
        size = equations.contact_scale(imp) / imp.time_scale() + abs(diff)
        assert _kernel_model.gdot(full, f, p) == pytest.approx(diff, abs=1e-6 * size)


@given(imp=impacts, unit=units, near=st.booleans())
def test_g_and_its_rate_together_are_gfun_and_gdot_to_the_last_bit(
    imp: Impact, unit: list[float], near: bool
) -> None:
    """The kernel's step takes g and g' at its end from `g_and_rate` (one power of |d| for both):
    the very numbers of gfun and gdot, on either side of d = 0, at it, and just off it."""
    _, full = states(imp, unit)
    if near:
        full[0] = full[2] + math.ldexp(unit[0], -1060)  # |d| subnormal, or 0
    p = fast.kernel_params(imp)
    f = np.zeros(6)
    _kernel_model.rhs(full, p, f)
    g, rate = _kernel_model.g_and_rate(full, f, p)
    assert repr((g, rate)) == repr((_kernel_model.gfun(full, p), _kernel_model.gdot(full, f, p)))


@given(imp=impacts, unit=units)
def test_the_series_damping_test_is_the_damping_rates(imp: Impact, unit: list[float]) -> None:
    """series_damped (from the series' powers of |d|) says what damping_rate > 0 says, in contact,
    but where the two sides of its comparison tie to rounding."""
    _, full = states(imp, unit)
    p = fast.kernel_params(imp)
    length = imp.params.compression_scale(imp.speed)
    full[0] = full[2] + max(abs(full[0] - full[2]), 1e-3 * length)  # in contact: d > 0
    S, aux = np.zeros((6, 3)), np.zeros((7, 3))
    assert _kernel_model.series(full, p, 2, S, aux)
    inv = 1.0 / p[0] + (p[9] if p[10] != 0.0 else 1.0 / p[5])
    d = full[0] - full[2]
    lam = p[2] * d ** p[4] * inv
    edge = 4.0 * p[1] * (1.0 + p[3]) * d ** p[3] * inv
    assume(abs(lam * lam - edge) > 1e-9 * max(lam * lam, edge))
    assert _kernel_model.series_damped(aux, p) == (_kernel_model.damping_rate(full, p) > 0.0)


def agree_across_switches(
    kernel: Callable[[float], float], reference: Callable[[float], float], grid: np.ndarray
) -> None:
    """kernel(x) == reference(x) on the grid and on both sides of each point where the reference's
    answer changes kind (zero, infinite, other; False, True), located to 1e-12 relative: a bound
    moved by a drifting coefficient answers otherwise there, however rarely random points fall near."""
    points = [float(x) for x in grid]
    for a, b in itertools.pairwise(grid.tolist()):
        if _kind(reference(a)) != _kind(reference(b)):
            points += _bracket(reference, a, b)
    assert [kernel(x) for x in points] == [reference(x) for x in points]


def _kind(value: float) -> tuple[bool, bool]:
    return value == 0.0, math.isinf(value)


def _bracket(f: Callable[[float], float], a: float, b: float) -> list[float]:
    """Both ends of a bisected interval around a change of f's kind between a and b."""
    kind = _kind(f(a))
    for _ in range(200):
        m = 0.5 * (a + b)
        if abs(b - a) <= 1e-12 * max(abs(a), abs(b)) or m in (a, b):
            break
        if _kind(f(m)) == kind:
            a = m
        else:
            b = m
    return [a, b]


def spread(scale: float, low: float, high: float) -> np.ndarray:
    """scale x (-high .. -low, low .. high), geometric: both signs, many decades."""
    side = np.geomspace(low, high, 200)
    return scale * np.concatenate([-side[::-1], side])


@given(imp=impacts, unit=units)
def test_the_damping_rate_switches_on_where_the_references_does(imp: Impact, unit: list[float]) -> None:
    reduced, full = states(imp, unit)
    p = fast.kernel_params(imp)
    x2 = reduced[2] if imp.n_states > 2 else 0.0

    def kernel(d: float) -> float:
        full[0] = full[2] + d
        return _kernel_model.damping_rate(full, p)

    def reference(d: float) -> float:
        reduced[0] = x2 + d
        return equations.damping_rate(imp, reduced)

    agree_across_switches(kernel, reference, spread(imp.params.compression_scale(imp.speed), 1e-9, 1e3))


@given(
    imp=flexible,
    d0=st.floats(-2.0, 2.0),
    amplitude=st.floats(0.0, 2.0),
    share=st.floats(0.01, 1.0),
    mass=st.floats(0.01, 1.0),
)
def test_the_re_contact_proof_is_the_references(
    imp: Impact, d0: float, amplitude: float, share: float, mass: float
) -> None:
    """g_cannot_rise over the ball's receding speed, for random constants and barrel motions."""
    length = imp.params.compression_scale(imp.speed)
    p = fast.kernel_params(imp)
    d0, amplitude, mu = d0 * length, amplitude * length, mass * imp.params.m2

    def kernel(recede: float) -> float:
        return _kernel_model.g_cannot_rise(d0, recede, amplitude, share, mu, p)

    def reference(recede: float) -> float:
        return equations.g_cannot_rise(imp, d0, recede, amplitude, share, mu)

    agree_across_switches(kernel, reference, spread(imp.speed, 1e-6, 1e6))


@given(imp=flexible, x1=st.floats(-50.0, 2.0), v1=st.floats(-4.0, 1.0), reach=st.floats(0.0, 2.0))
def test_the_clamped_barrels_escape_bound_is_the_references(
    imp: Impact, x1: float, v1: float, reach: float
) -> None:
    """force_escape_time over the ball's position, then over its speed."""
    length = imp.params.compression_scale(imp.speed)
    p = fast.kernel_params(imp)
    x1, v1, reach = x1 * length, v1 * imp.speed, reach * length
    agree_across_switches(
        lambda x: _kernel_model.force_escape_time(x, v1, reach, p),
        lambda x: equations._force_escape_time(imp, x, v1, reach),
        spread(length, 1e-6, 1e6),
    )
    agree_across_switches(
        lambda v: _kernel_model.force_escape_time(x1, v, reach, p),
        lambda v: equations._force_escape_time(imp, x1, v, reach),
        spread(imp.speed, 1e-6, 1e6),
    )
