"""`fast.solve`'s lean compiled entry (`_dop853.solve_impact`: the parameter vector, length scale,
state count and time limit made inside the kernel, the state returned as numbers) must give the
result of the general path (`fast.solve_general`: those made in Python, then `solve_one`) to the
last bit, failures included, over the model's hard corners: stiff contacts (light barrels, strong
ball damping), near-rigid barrels (hoop up to 1 MHz), very slow and very fast balls, a free body,
and low hoop frequencies whose ball meets the barrel again (the general path's ending follows)."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from rig.core.errors import SolverError
from rig.physics import fast
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from rig.physics.reference import CollisionResult, bounded_cor


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(math.log(lo), math.log(hi)).map(lambda x: min(max(math.exp(x), lo), hi))


EXPONENT = st.sampled_from([0.0, 1.0]) | st.floats(0.0, 1.0)


@st.composite
def corners(draw: st.DrawFn) -> Impact:
    """A collision from the hard-corner space (hoop None: rigid; body None: clamped)."""
    params = CollisionParams.build(
        m1=draw(st.just(0.145) | log_uniform(0.01, 1.0)),
        k1=draw(st.just(60e6) | log_uniform(1e4, 1e10)),
        m2=draw(st.just(0.09) | log_uniform(1e-4, 1e4)),
        a=draw(EXPONENT),
        b=draw(EXPONENT),
        c1=draw(st.sampled_from([0.0, 5000.0]) | log_uniform(1.0, 1e5)),
        c2=draw(st.sampled_from([0.0, 100.0]) | log_uniform(1.0, 1e4)),
    )
    hoop = draw(st.none() | st.sampled_from([100.0, 1e6]) | log_uniform(50.0, 1e6))
    body = draw(st.none() | log_uniform(0.05, 5.0))
    speed = draw(st.sampled_from([0.01, 100.0]) | log_uniform(0.01, 100.0))
    return Impact(params, speed, hoop, body)


def outcome(solve: object, imp: Impact, rtol: float) -> CollisionResult | str:
    """The result, or the failure's message."""
    try:
        return solve(imp, rtol)  # type: ignore[operator, no-any-return]
    except SolverError as exc:
        return str(exc)


def same(a: CollisionResult | str, b: CollisionResult | str) -> bool:
    """Equal to the last bit (NaN equals NaN; -0.0 is told from 0.0)."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    left, right = vars(a), vars(b)
    return all(repr(left[k]) == repr(right[k]) for k in left) and left.keys() == right.keys()


@settings(max_examples=80, deadline=None)
@given(imp=corners(), rtol=st.sampled_from([1e-6, 3e-8, 1e-10, 1e-12]))
@example(imp=Impact(DEFAULT_PARAMS, 60.8, 1250.0), rtol=3e-8)  # the benchmark's solve
@example(imp=Impact(DEFAULT_PARAMS, 60.8, 150.0), rtol=1e-10)  # the ball meets the barrel again
@example(imp=Impact(DEFAULT_PARAMS, 60.8, None, 0.6), rtol=1e-10)  # rigid barrel on a free body
@example(imp=Impact(CollisionParams.build(m2=1e-4, b=0.0, c1=1e5), 100.0, 1e6), rtol=1e-12)  # stiff
def test_the_lean_entry_gives_the_general_paths_result_to_the_last_bit(imp: Impact, rtol: float) -> None:
    kernel = fast.compiled()  # the lean entry is the compiled kernel's
    lean = outcome(fast.solve, imp, rtol)
    general = outcome(lambda i, r: fast.solve_general(i, r, kernel), imp, rtol)
    assert same(lean, general), (lean, general)


def test_the_comparison_can_tell_a_last_bit_apart() -> None:
    """`same` is the test's only judge: it must see one ulp, a sign of zero and a different ending."""
    fast.compiled()
    res = fast.solve(Impact(DEFAULT_PARAMS, 60.8, 1250.0), 3e-8)
    nudged = CollisionResult(**{**vars(res), "cor": math.nextafter(res.cor, 2.0)})
    assert same(res, res) and not same(res, nudged)
    zero = CollisionResult(**{**vars(res), "final_state": (*res.final_state[:4], -0.0, 0.0)})
    assert not same(res, zero)
    assert not same(res, "step budget exhausted before contact ended")


def test_a_failure_reads_the_same_on_both_paths(monkeypatch: pytest.MonkeyPatch) -> None:
    """A contact that cannot end within the step budget (cut to 10 steps, which both paths read
    at the call): the same one-line error either way."""
    kernel = fast.compiled()
    monkeypatch.setattr(fast, "MAX_STEPS", 10)
    imp = Impact(DEFAULT_PARAMS, 60.8, 1250.0)
    with pytest.raises(SolverError) as lean:
        fast.solve(imp, 1e-12)
    with pytest.raises(SolverError) as general:
        fast.solve_general(imp, 1e-12, kernel)
    assert str(lean.value) == str(general.value)


def test_the_lean_result_is_the_dataclass_built_by_its_own_init() -> None:
    """`fast.solve`'s result is built without CollisionResult.__init__ (for speed): it must be the
    object that __init__ builds, field for field and in order, still frozen, with its own energy dict."""
    state = (1.0, -30.4, 2.0, 3.0, 0.0, 0.0)
    for cor in (0.5, -0.25, 1.0 + 1e-15, -1.0 - 1e-15, math.inf, -math.inf, math.nan, -0.0):
        out = (cor, 1e-3, 295, fast.kernel.STATUS_OK, *state)
        built = fast._single_contact(out, 3e-8)
        init = CollisionResult(bounded_cor(cor), 1e-3, -30.4, state, 295, "rig-DOP853", 3e-8, {}, 1)
        assert type(built) is CollisionResult
        assert list(vars(built).items()) == list(vars(init).items()), cor
        assert repr(built.cor) == repr(init.cor), cor  # the clip as bounded_cor's: -0.0 kept, NaN to -1
    with pytest.raises(dataclasses.FrozenInstanceError):
        built.cor = 0.4  # type: ignore[misc]
    assert dataclasses.replace(built, cor=0.4).cor == 0.4
    assert built.energy is not fast._single_contact(out, 3e-8).energy
