"""The kernel's stage sums were rewritten for speed (issue 26: the tables' nonzero terms only, the
moving states only, each state's sum in its own chain): it must give the numbers of the kernel it
replaced. That kernel's text is kept as it was (data/dop853_before_issue26.py.txt) and run by the
interpreter, on the same model (`_kernel_model`, whose pinned digest it checks: its MODEL_DIGEST
line follows the model's text, to which only functions it does not call were added since, the
Taylor series), against the compiled kernel of today, over random impacts, tolerances and models."""

from __future__ import annotations

import importlib.util
import math
import sys
from importlib.machinery import SourceFileLoader
from pathlib import Path
from types import ModuleType

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.physics import _dop853, fast
from rig.physics.equations import Impact
from tests.physics.test_kernel_model import impacts

BEFORE = Path(__file__).parent / "data" / "dop853_before_issue26.py.txt"
NAME = "tests_dop853_before_issue26"


def before() -> ModuleType:
    """The kernel as it was, interpreted (its numba stand-ins come from _jit: not its own name)."""
    if NAME in sys.modules:
        return sys.modules[NAME]
    loader = SourceFileLoader(NAME, str(BEFORE))
    spec = importlib.util.spec_from_loader(NAME, loader)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    sys.modules[NAME] = module
    return module


def close(new: float, old: float) -> bool:
    """Equal to 1e-12 relative (NaN, a failed solve's COR, equals NaN)."""
    if math.isnan(old) or math.isnan(new):
        return math.isnan(old) and math.isnan(new)
    return abs(new - old) <= 1e-12 * max(abs(old), 1e-300)


@settings(max_examples=40, deadline=None)
@given(imp=impacts, rtol=st.sampled_from([1e-6, 1e-8, 1e-10]))
def test_the_kernel_gives_the_numbers_of_the_kernel_it_replaced(imp: Impact, rtol: float) -> None:
    scale = imp.params.compression_scale(imp.speed)
    limits = (fast._time_limit(imp), 20_000)  # a step budget the interpreter gets through in a second
    args = (fast.kernel_params(imp), imp.speed, scale, rtol, imp.n_states, *limits)
    s_old, s_new = np.zeros(6), np.zeros(6)
    old = before().solve_one(*args, s_old)
    new = _dop853.solve_one(*args, s_new, 0)
    assert new[4] == old[4]  # status: the same ending (ok, re-contact possible, or the same failure)
    assert new[2:4] == old[2:4]  # the same evaluations and steps: the same steps were taken
    assert close(new[0], old[0]) and close(new[1], old[1])  # COR and contact time
    size = np.tile([scale, imp.speed], 3)
    assert np.all(np.abs(s_new - s_old) <= 1e-12 * np.maximum(np.abs(s_old), size))
