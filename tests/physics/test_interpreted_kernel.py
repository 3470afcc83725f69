"""The kernel run by the interpreter gives the compiled kernel's numbers, and single solves start
interpreted and switch to the compiled kernel (numba) only when enough are asked for."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate._ivp import dop853_coefficients as scipy_tables

from rig.physics import _dop853, _interpreted, _kernel_model, fast
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from tests.physics.test_lean_solve import corners

CASES = [
    (60.8, 1276.0, None),
    (60.8, None, None),
    (45.0, 3600.0, 0.6),
    (60.8, 900.0, None),
    (1.0, 100.0, None),
]


@pytest.mark.parametrize(("speed", "hoop", "body"), CASES)
def test_interpreted_kernel_gives_the_compiled_kernels_numbers(
    speed: float, hoop: float | None, body: float | None
) -> None:
    imp = Impact(DEFAULT_PARAMS, speed, hoop, body_mass=body)
    args = (fast.kernel_params(imp), imp.speed, imp.params.compression_scale(imp.speed), 1e-10, imp.n_states)
    limits = (fast._time_limit(imp), fast.MAX_STEPS)
    s1, s2 = np.zeros(6), np.zeros(6)
    one = _interpreted.load().solve_one(*args, *limits, s1, 0)
    two = _dop853.solve_one(*args, *limits, s2, 0)
    assert [float(x) for x in one] == [float(x) for x in two]  # cor, contact time, nfev, steps, status
    assert s1.tolist() == s2.tolist()


@settings(max_examples=12, deadline=None)
@given(imp=corners(), rtol=st.sampled_from([1e-4, 1e-6, 3e-8, 1e-10]))
@example(  # a stiff free body of thousands of steps: parted after 546 when a square was pow(q, 2)
    imp=Impact(
        CollisionParams.build(
            m1=0.37036689299373043,
            k1=34441.8347388482,
            c1=212.15690500757484,
            a=0.0675449302477894,
            b=0.0,
            m2=0.08223723767673474,
            c2=100.0,
        ),
        100.0,
        37985.628932388354,
        0.518135327573594,
    ),
    rtol=3e-8,
)
@example(imp=Impact(DEFAULT_PARAMS, 60.8, 6946.289938909197), rtol=1e-10)  # pow(w, 2) != w * w for k2
def test_the_two_kernels_agree_to_the_last_bit_over_the_hard_corners(imp: Impact, rtol: float) -> None:
    """Every square in the kernel is q * q: the interpreter takes q ** 2 as the C library's pow(q, 2),
    a last bit off about once in 1,000, which near-rigid barrels' thousands of steps then carry
    apart (an outside review found 23 of 400 random corners differing). At most 700 steps, the
    same stopping point for both."""
    args = (fast.kernel_params(imp), imp.speed, imp.params.compression_scale(imp.speed), rtol, imp.n_states)
    s1, s2 = np.zeros(6), np.zeros(6)
    one = _interpreted.load().solve_one(*args, fast._time_limit(imp), 700, s1, 0)
    two = _dop853.solve_one(*args, fast._time_limit(imp), 700, s2, 0)
    assert repr([float(x) for x in one]) == repr([float(x) for x in two])
    assert repr(s1.tolist()) == repr(s2.tolist())


def test_the_tables_are_scipys() -> None:
    kernel = _interpreted.load()
    for name in ("A", "B", "C", "E3", "E5", "D"):
        assert np.array_equal(getattr(kernel, f"_{name}"), getattr(scipy_tables, name))


def fresh_python(*lines: str, timeout: float = 300) -> list[str]:
    """The words a fresh interpreter prints running `lines` (rig's imports as a process starts)."""
    code = "\n".join(lines) + "\n"
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=timeout
    ).stdout.split()


def test_single_solves_start_interpreted_and_switch_to_the_compiled_kernel() -> None:
    out = fresh_python(
        "import sys",
        "from rig.physics import fast",
        "from rig.physics.equations import Impact",
        "from rig.physics.params import DEFAULT_PARAMS",
        "imp = Impact(DEFAULT_PARAMS, 60.8, 1276.0)",
        "first = fast.solve(imp).cor",
        "print('numba' in sys.modules)",
        "for _ in range(fast.INTERPRETED_SOLVES): fast.solve(imp)",
        "print('numba' in sys.modules, fast.solve(imp).cor == first)",
    )
    assert out == ["False", "True", "True"]


def test_a_long_solve_goes_to_the_compiled_kernel_at_once() -> None:
    """A single solve longer than INTERPRETED_MAX_STEPS (cut to 10 here) is not left to the
    interpreter (a stiff one of 2e6 steps took 4 minutes there): the compiled kernel solves it, with
    the numbers it gives any solve."""
    out = fresh_python(
        "import sys",
        "from rig.physics import fast",
        "from rig.physics.equations import Impact",
        "from rig.physics.params import DEFAULT_PARAMS",
        "fast.INTERPRETED_MAX_STEPS = 10",
        "res = fast.solve(Impact(DEFAULT_PARAMS, 60.8, 1276.0))",
        "print('rig.physics._dop853' in sys.modules, repr(res.cor), res.nfev)",
    )
    fast.compiled()
    ref = fast.solve(Impact(DEFAULT_PARAMS, 60.8, 1276.0))
    assert out == ["True", repr(ref.cor), str(ref.nfev)]
    assert ref.nfev > 12 * 10  # more than 10 steps: the interpreter's budget was indeed too short


def test_the_interpreted_kernel_is_the_compiled_kernels_file_unedited_and_needs_no_numba() -> None:
    """One source: the interpreted kernel is _dop853.py executed as it is, under another name, and
    loading it does not load numba (the point of having it)."""
    numba_loaded, file, solve_file, rhs_file = fresh_python(
        "import sys",
        "from rig.physics import _interpreted",
        "k = _interpreted.load()",
        "print('numba' in sys.modules, k.__file__, k.solve_one.__code__.co_filename,"
        " k._rhs.__code__.co_filename)",
        timeout=120,
    )
    assert numba_loaded == "False"
    assert file == solve_file == _dop853.__file__
    assert rhs_file == _kernel_model.__file__  # the model's functions: their one definition
    kernel = _interpreted.load()
    for name in ("_rhs", "_gfun", "_gdot", "_damping_rate", "solve_one"):
        assert getattr(kernel, name).__code__.co_code == getattr(_dop853, name).py_func.__code__.co_code
