"""The compiled kernel sums its stages in vectors (`_dop853._vector_sums`, LLVM IR written out):
the same products added in the same order, so the same numbers to the last bit as the plain
loop the interpreted kernel runs (`_combine`, `_step_sums` as written in Python). Checked over
random stages, every table's rows, and the three sizes of state (2, 4 and 6 moving states, the
others' K at +0 or -0, as the right-hand side leaves them), including infinities and NaN."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba.core.errors import TypingError

from rig.physics import _dop853, _interpreted

PLAIN = _interpreted.load()
ROWS = [
    (_dop853._A_COL, _dop853._A_VAL, int(lo), int(hi))
    for lo, hi in zip(_dop853._A_START[1:-1], _dop853._A_START[2:], strict=True)
]
ROWS += [
    (_dop853._D_COL, _dop853._D_VAL, int(lo), int(hi))
    for lo, hi in zip(_dop853._D_START[:-1], _dop853._D_START[1:], strict=True)
]
ROWS += [(_dop853._B_COL, _dop853._B_VAL, 0, _dop853._B_COL.size)]

values = st.floats(-1e3, 1e3) | st.sampled_from([0.0, -0.0, 1e-300, -1e300, math.inf, -math.inf, math.nan])


@st.composite
def stages(draw: st.DrawFn) -> tuple[np.ndarray, int]:
    """K of _NX stages, with n moving states; the others +-0."""
    n = draw(st.sampled_from([2, 4, 6]))
    K = np.array(draw(st.lists(values, min_size=_dop853._NX * 6, max_size=_dop853._NX * 6))).reshape(
        _dop853._NX, 6
    )
    signs = draw(st.lists(st.booleans(), min_size=_dop853._NX * 6, max_size=_dop853._NX * 6))
    zeros = np.where(np.array(signs).reshape(_dop853._NX, 6), 0.0, -0.0)
    K[:, n:] = zeros[:, n:]
    return K, n


def bits(sums: tuple[float, ...], n: int) -> list[str]:
    return [repr(float(x)) for x in sums[:n]]


@settings(max_examples=200, deadline=None)
@given(case=stages(), row=st.sampled_from(range(len(ROWS))))
def test_the_vector_sums_are_the_plain_loops_to_the_last_bit(case: tuple[np.ndarray, int], row: int) -> None:
    K, n = case
    cols, vals, lo, hi = ROWS[row]
    vector = _dop853._combine(K, cols, vals, lo, hi, n)
    with np.errstate(all="ignore"):  # inf - inf in the plain loop's numpy scalars: NaN, as compiled
        plain = PLAIN._combine(K, cols, vals, lo, hi, n)
    assert bits(vector, n) == bits(plain, n)
    # the states that do not move: a sum of +-0 terms, which adds +-0 to their 0 (or NaN with them)
    y = np.zeros(6)
    out_vector, out_plain = np.zeros(6), np.zeros(6)
    _dop853._advance(y, 1e-3, vector, out_vector)
    with np.errstate(all="ignore"):
        PLAIN._advance(y, 1e-3, plain, out_plain)
    finite = np.all(np.isfinite(K[:, :n]))
    if finite:
        assert [repr(x) for x in out_vector] == [repr(x) for x in out_plain]


@settings(max_examples=100, deadline=None)
@given(case=stages())
def test_the_steps_three_sums_in_one_pass_are_the_plain_loops(case: tuple[np.ndarray, int]) -> None:
    K, n = case
    with np.errstate(all="ignore"):
        plain_sums = PLAIN._step_sums(K, n)
    for vector, plain in zip(_dop853._step_sums(K, n), plain_sums, strict=True):
        assert bits(vector, n) == bits(plain, n)


def test_a_stage_table_not_laid_out_as_the_kernels_is_refused() -> None:
    """The vector sums read K as C-ordered rows of 6 float64 (an outside review summed a
    row-strided K to -12.79 where the plain loop gave 7.94): any other K is refused, not misread."""
    cols, vals = _dop853._B_COL, _dop853._B_VAL
    K = np.arange(_dop853._NX * 6, dtype=float).reshape(_dop853._NX, 6)
    strided = np.repeat(K, 2, axis=0)[::2]
    assert np.array_equal(strided, K) and not strided.flags.c_contiguous
    with pytest.raises(TypingError, match="C-ordered"):
        _dop853._combine(strided, cols, vals, 0, cols.size, 6)
    with pytest.raises(ValueError, match="6 states"):
        _dop853._combine(np.zeros((_dop853._NX, 4)), cols, vals, 0, cols.size, 4)
    with pytest.raises(ValueError, match="6 states"):
        _dop853._step_sums(np.zeros((_dop853._NX, 4)), 4)
    assert bits(_dop853._combine(K, cols, vals, 0, cols.size, 6), 6) == bits(
        PLAIN._combine(K, cols, vals, 0, cols.size, 6), 6
    )
