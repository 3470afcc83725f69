"""Accuracy against lab time: the table, its systematic floor, and hits needed for a target U."""

from __future__ import annotations

import itertools
import math

import pytest

from rig.core.errors import ParameterError
from rig.measure.tradeoff import hits_needed, lab_time_s, mean_u, tradeoff_table
from rig.measure.uncertainty import budget
from tests.measure.shots import typical_shot


@pytest.fixture(scope="module")
def per_hit():
    return budget(typical_shot())


def test_table_rows_match_the_joint_budget_of_n_hits(per_hit) -> None:
    rows = tradeoff_table(per_hit)
    assert [r.hits for r in rows] == list(range(1, 21))
    six = budget([typical_shot()] * 6)
    assert rows[5].u == pytest.approx(six.u_of("bbcor"), rel=1e-9)
    assert rows[5].expanded == pytest.approx(2 * six.u_of("bbcor"), rel=1e-9)
    assert set(rows[0].as_dict()) == {"hits", "u", "expanded", "shots", "lab_time_s"}


def test_u_flattens_at_the_floor_while_time_grows(per_hit) -> None:
    rows = tradeoff_table(per_hit)
    us = [r.u for r in rows]
    assert all(a >= b for a, b in itertools.pairwise(us))
    assert us[-1] >= math.sqrt(per_hit.systematic_variance("bbcor"))
    times = [r.lab_time_s for r in rows]
    assert all(a < b for a, b in itertools.pairwise(times))


def test_lab_time_counts_cycles_and_ring_checks(per_hit) -> None:
    assert lab_time_s(6, cycle_s=60.0, ring_check_s=20.0) == 6 * 60 + 7 * 20
    rows = tradeoff_table(per_hit, cycle_s=60.0, ring_check_s=20.0, valid_fraction=0.8)
    assert rows[5].shots == 8  # 6 valid hits at 80 % validity
    assert rows[5].lab_time_s == 8 * 60 + 9 * 20
    assert rows[3].shots == 5  # exactly 4 / 0.8: no spurious extra shot from rounding


def test_hits_needed(per_hit) -> None:
    floor_U = 2 * math.sqrt(per_hit.systematic_variance("e_a"))
    assert floor_U == 0.0  # e_A has no systematic input with these gates
    U1 = per_hit.expanded("e_a")
    target = U1 / 2.9  # 1/sqrt(n) <= 1/2.9 first at n = 9
    n = hits_needed(per_hit, target, output="e_a")
    assert n is not None
    assert 2 * mean_u(per_hit, n, "e_a") <= target < 2 * mean_u(per_hit, n - 1, "e_a")
    assert n == 9
    assert hits_needed(per_hit, U1 * 1.01, output="e_a") == 1
    # BBCOR: the MOI floor sits above this target whatever the number of hits
    bb_floor = 2 * math.sqrt(per_hit.systematic_variance("bbcor"))
    assert hits_needed(per_hit, bb_floor * 0.999) is None
    assert hits_needed(per_hit, bb_floor * 1.001) is not None


def test_refusals(per_hit) -> None:
    with pytest.raises(ParameterError):
        tradeoff_table(budget([typical_shot()] * 2))
    with pytest.raises(ParameterError):
        tradeoff_table(per_hit, valid_fraction=0.0)
    with pytest.raises(ParameterError):
        mean_u(per_hit, 0)
