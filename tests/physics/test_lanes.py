"""The numpy lanes (`_lanes`) give the compiled kernel's numbers to the last bit, on the hard corners
(stiff contact, near-rigid and rigid barrels, tiny and large speeds, re-contacts, brief separations
inside a step, the step and time limits) and over random draws from them; and a cross-check runs in
them without loading numba."""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.physics import _dop853, _lanes, fast
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from rig.physics.reference import _time_limit

STATUS = ("cor", "tc", "nfev", "status", "states")
BALL = DEFAULT_PARAMS.model_copy(update={"m1": 0.1417})
STIFF = CollisionParams.build(b=0.0)  # the damping rate bounds the step that holds the contact's end


def run(
    solve_many: object, impacts: Sequence[Impact], rtol: float, max_steps: int, t_scale: float = 1.0
) -> dict[str, np.ndarray]:
    """solve_many's results for the impacts (its lanes built as fast.solve_batch builds them)."""
    n = len(impacts)
    P = np.array([fast.kernel_params(imp) for imp in impacts])
    v0 = np.array([imp.speed for imp in impacts])
    length = np.array([imp.params.compression_scale(imp.speed) for imp in impacts])
    n_active = np.array([imp.n_states for imp in impacts], dtype=np.int64)
    t_max = t_scale * np.array([_time_limit(imp) for imp in impacts])
    out = {
        "cor": np.empty(n),
        "tc": np.empty(n),
        "nfev": np.empty(n, dtype=np.int64),
        "status": np.empty(n, dtype=np.int64),
        "states": np.zeros((n, 6)),
    }
    assert callable(solve_many)
    solve_many(P, v0, length, rtol, n_active, t_max, max_steps, *(out[k] for k in STATUS), 0)
    return out


def assert_same(
    impacts: Sequence[Impact], rtol: float, max_steps: int = fast.MAX_STEPS, t_scale: float = 1.0
) -> np.ndarray:
    """Lanes and compiled kernel agree bit for bit; returns the statuses."""
    lanes = run(_lanes.solve_many, impacts, rtol, max_steps, t_scale)
    compiled = run(_dop853.solve_many, impacts, rtol, max_steps, t_scale)
    for key in STATUS:
        np.testing.assert_array_equal(lanes[key], compiled[key], err_msg=key)
    return lanes["status"]


def spread(params: CollisionParams, speeds: Sequence[float], hoops: Sequence[float | None]) -> list[Impact]:
    """Every speed and hoop, on a clamped barrel and on a pivoted bat (body 0.8 kg)."""
    return [Impact(params, s, h, body_mass=b) for s in speeds for h in hoops for b in (None, 0.8)]


CASES = {
    "pivoted bats of a population": [
        Impact(BALL.model_copy(update={"m2": 0.24, "c2": 300.0}), 60.8, h, body_mass=b)
        for h, b in zip(np.linspace(1400.0, 3000.0, 24), np.linspace(0.3, 1.5, 24), strict=True)
    ],
    "stiff contact (b = 0)": spread(STIFF, (1.0, 60.8), (None, 1250.0, 1e5)),
    "near-rigid and rigid barrels": spread(DEFAULT_PARAMS, (60.8,), (None, 1e5, 1e6)),
    "tiny and large speeds": spread(DEFAULT_PARAMS, (0.01, 0.5, 150.0), (None, 1250.0)),
    "low hoops (re-contacts)": spread(DEFAULT_PARAMS, (60.8,), (100.0, 157.0, 300.0)),
}


@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
@pytest.mark.parametrize("case", sorted(CASES))
def test_lanes_give_the_compiled_kernels_numbers_on_hard_cases(case: str, rtol: float) -> None:
    statuses = assert_same(CASES[case], rtol)
    assert set(statuses) <= {_dop853.STATUS_OK, _dop853.STATUS_FOLLOW}
    if case.startswith("low hoops"):
        assert _dop853.STATUS_FOLLOW in statuses  # the lanes hand re-contacts on as the kernel does


def test_lanes_stop_where_the_compiled_kernel_stops() -> None:
    """The step budget and the time limit end a lane with the kernel's status, time and count."""
    impacts = CASES["pivoted bats of a population"][:6]
    assert set(assert_same(impacts, 1e-9, max_steps=7)) == {_dop853.STATUS_MAX_STEPS}
    assert set(assert_same(impacts, 1e-9, t_scale=1e-4)) == {_dop853.STATUS_TIME_LIMIT}


SPEEDS = st.one_of(st.sampled_from([0.01, 150.0]), st.floats(math.log(0.01), math.log(150.0)).map(math.exp))
HOOPS = st.one_of(
    st.none(), st.sampled_from([100.0, 1e5]), st.floats(math.log(100.0), math.log(1e5)).map(math.exp)
)


@st.composite
def corner(draw: st.DrawFn) -> Impact:
    """A collision from the corners: exponents at 0, 1 and between, no damping, heavy and light barrels."""
    params = CollisionParams.build(
        m2=draw(st.sampled_from([0.01, 0.09, 1.0, 100.0])),
        a=draw(st.one_of(st.sampled_from([0.0, 1.0]), st.floats(0.0, 1.0))),
        b=draw(st.one_of(st.sampled_from([0.0, 1.0]), st.floats(0.0, 1.0))),
        c1=draw(st.sampled_from([0.0, 10.0, 5000.0])),
        c2=draw(st.sampled_from([0.0, 100.0, 1e4])),
    )
    body = draw(st.one_of(st.none(), st.sampled_from([0.05, 0.8, 50.0])))
    return Impact(params, draw(SPEEDS), draw(HOOPS), body_mass=body)


@settings(max_examples=30, deadline=None)
@given(st.lists(corner(), min_size=1, max_size=6), st.sampled_from([1e-6, 1e-9, 1e-11]))
def test_lanes_give_the_compiled_kernels_numbers_over_the_corners(impacts: list[Impact], rtol: float) -> None:
    assert_same(impacts, rtol, max_steps=3000)  # a lane out of steps: the same status in both


def test_a_small_batch_that_asks_for_lanes_gets_them_only_while_numba_is_not_loaded() -> None:
    code = (
        "import sys\n"
        "from rig.physics import fast\n"
        "from rig.physics.equations import Impact\n"
        "from rig.physics.params import DEFAULT_PARAMS\n"
        "imps = [Impact(DEFAULT_PARAMS, 60.8, h, body_mass=0.8) for h in (1300.0, 2500.0)]\n"
        "lanes = fast.solve_batch(imps, numpy_lanes=True)\n"
        "print('numba' in sys.modules)\n"
        "fast._batch_kernel(fast.NUMPY_LANES + 1, True)\n"  # too many lanes: the compiled kernel
        "print('numba' in sys.modules, fast._batch_kernel(2, True) is fast.compiled().solve_many)\n"
        "compiled = fast.solve_batch(imps, numpy_lanes=True)\n"
        "print((lanes[0] == compiled[0]).all(), (lanes[1] == compiled[1]).all())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    ).stdout
    assert out.split() == ["False", "True", "True", "True", "True"]
