"""A ball creeping off an over-damped barrel: the reference's refusal is foreseen, not stepped to.

`reference._Phases._foresee` refuses a free flight as soon as it is proved to need more steps than
the budget allows; before, the flight was stepped until the budget ran out (~3 CPU-s a case). These
tests hold the foreseen refusals to the stepped ones: both refuse the same cases, and where the
stepped path solves, the foreseeing one returns the very same numbers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.core.errors import SolverError
from rig.physics import fast, reference
from rig.physics.equations import Impact, cannot_touch, creep_rates, escape_time
from rig.physics.params import CollisionParams

# The 0.1 g barrel on a 100 Hz spring (c2 / m2 = 1e6 /s): its fast mode decays at f = 1e6 /s, so
# DOP853 steps at 6.39 / f on average. Each case: (b, speed, time and state at the kernel's first
# separation, recorded). At the full budget the stepped path refused all three after 40000 steps
# (~0.26 s of a flight of 2.5 to 5 s), ~3 CPU-s each.
LIGHT_BARREL_SEPARATIONS = {
    "b0-slow": (
        0.0,
        0.01,
        0.021953416382907067,
        [1.4678008823727968e-05, -5.874887360336373e-06, 1.439173775005881e-05, -5.681630162729803e-06],
    ),
    "b0-fast": (
        0.0,
        100.0,
        0.012621229713540008,
        [0.1451177785214272, -0.1137469435500409, 0.14452706108715246, -0.05704836025261162],
    ),
    "paper-b-fast": (
        0.5202,
        100.0,
        0.012914140098820807,
        [0.1444480832280981, -0.06796447090232437, 0.1444436008951781, -0.057021762218942146],
    ),
}
SMALL_BUDGET = 400  # steps: the stepped path reaches a refusal in ~30 ms


def light_barrel(b: float, speed: float) -> Impact:
    return Impact(CollisionParams.build(m2=1e-4, b=b), speed, 100.0)


@pytest.mark.parametrize("case", sorted(LIGHT_BARREL_SEPARATIONS))
def test_creeping_off_a_light_barrel_is_foreseen(case: str) -> None:
    """The full solve refuses with "creeps off", foreseen; the stepped path refuses the same flight."""
    b, speed, t, state = LIGHT_BARREL_SEPARATIONS[case]
    imp = light_barrel(b, speed)
    with pytest.raises(SolverError, match="creeps off") as solved:
        fast.solve(imp)
    assert "foreseen" in str(solved.value)
    rtol = fast.DEFAULT_RTOL
    with pytest.raises(SolverError, match="creeps off") as stepped:
        reference.continue_contacts(imp, t, state, rtol, budget=SMALL_BUDGET, foresee=False)
    assert "foreseen" not in str(stepped.value)
    with pytest.raises(SolverError, match=r"creeps off.*foreseen"):
        reference.continue_contacts(imp, t, state, rtol, budget=SMALL_BUDGET)


def flight_start(kind: str, when: float) -> tuple[Impact, np.ndarray]:
    """A free flight over the light barrel (creeping back from 5 cm on its slow mode) whose ball
    leaves `when` s before it is out of reach ("leaves"), or meets the barrel after `when` s ("meets")."""
    imp = light_barrel(0.5202, 1.0)
    rates = creep_rates(imp)
    assert rates is not None
    x2 = 0.05
    v2 = -rates[0] * x2
    if kind == "leaves":  # receding at 1 m/s from behind the barrel's reach
        v1 = -1.0
        x1 = -math.hypot(x2, v2 * math.sqrt(imp.params.m2 / imp.k2)) + when
    else:  # approaching the barrel at 2 mm/s (it is out of reach only seconds later)
        v1 = v2 + 2e-3
        x1 = x2 - 2e-3 * when
    return imp, np.array([x1, v1, x2, v2])


# about the stepped path's boundary at SMALL_BUDGET (400 steps of 6.39 us: 2.56 ms) and the
# foreseeing one's (256 steps, 1.64 ms, then 145 steps of at most 4 times the average: 5.35 ms)
BOUNDARY_FLIGHTS = [("leaves", w) for w in (1.5e-3, 2.4e-3, 2.7e-3, 5.0e-3, 5.6e-3)] + [
    ("meets", w) for w in (4.5e-3, 6e-3)
]


def test_foreseeing_refuses_nothing_that_stepping_solves() -> None:
    """Flights on both sides of the two boundaries: wherever the foreseeing path refuses, the stepped
    one refuses too; wherever the stepped one solves, the foreseeing one returns the same numbers.

    Both outcomes must occur, and foreseen refusals too, or the flights miss the boundaries.
    """
    seen = set()
    for kind, when in BOUNDARY_FLIGHTS:
        imp, y = flight_start(kind, when)
        assert 0.0 < escape_time(imp, y) < math.inf
        outcomes = []
        for foresee in (False, True):
            try:
                out = reference.continue_contacts(imp, 0.0, y, 1e-10, budget=SMALL_BUDGET, foresee=foresee)
            except SolverError as exc:
                assert "creeps off" in str(exc), (kind, when)
                outcomes.append("foreseen" if "foreseen" in str(exc) else "refused")
            else:
                outcomes.append(out)
        stepped, foreseeing = outcomes
        if isinstance(stepped, str):
            assert isinstance(foreseeing, str), (kind, when)
            seen.add(foreseeing)
        else:
            assert not isinstance(foreseeing, str), (kind, when, foreseeing)
            assert stepped[0] == foreseeing[0] and stepped[2:] == foreseeing[2:], (kind, when)
            assert np.array_equal(stepped[1], foreseeing[1]), (kind, when)
            seen.add("solved")
    assert seen == {"solved", "refused", "foreseen"}


def test_cannot_touch_sees_a_contact_in_its_window() -> None:
    """The closed-form bound proves nothing for a window that holds the meeting, and proves the
    flight contact-free up to just before it (the bound is not so loose as to prove nothing)."""
    imp, y = flight_start("meets", 5e-3)
    assert not cannot_touch(imp, y, 5.1e-3, 1e-7, 1e-13, 1e-12)
    assert cannot_touch(imp, y, 4.9e-3, 1e-7, 1e-13, 1e-12)
    # a rigid, a clamped under-damped or a free-based barrel: no closed form here, no proof
    for other in (
        Impact(imp.params, 1.0),
        Impact(CollisionParams.build(m2=1e-4, c2=1e-3), 1.0, 100.0),
        Impact(imp.params, 1.0, 100.0, body_mass=1.0),
    ):
        assert creep_rates(other) is None
        assert not cannot_touch(other, np.append(y, [0.0, 0.0]), 1e-3, 0.0, 0.0, 0.0)
