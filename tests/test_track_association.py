"""The tracker's association of tracks to detections (:func:`fuzzynav.sensing.tracking.associate`): the case
without conflicts, taken without the Hungarian method, gives the pairs ``linear_sum_assignment`` gives."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.optimize import linear_sum_assignment

from fuzzynav.sensing.tracking import associate


def hungarian(cost: np.ndarray, inside: np.ndarray) -> dict[int, int]:
    rows, cols = linear_sum_assignment(np.where(inside, cost, 1e9))
    return {int(c): int(r) for r, c in zip(rows, cols, strict=True) if inside[r, c]}


@st.composite
def problems(draw):
    shape = (draw(st.integers(1, 6)), draw(st.integers(1, 6)))
    # few distinct distances (ties) and sparse or dense gates: both the fast case and conflicts
    cost = draw(arrays(np.float64, shape, elements=st.sampled_from([0.0, 5.0, 12.5, 40.0, 79.9, 250.0])))
    gate = draw(st.sampled_from([3.0, 13.0, 80.0, 300.0]))
    return cost, cost <= gate


@settings(max_examples=600, deadline=None)
@given(problems())
def test_the_assignment_is_the_hungarian_methods(problem):
    cost, inside = problem
    assert associate(cost, inside) == hungarian(cost, inside)


def test_disjoint_gated_pairs_are_the_assignment():
    cost = np.array([[10.0, 900.0, 900.0], [900.0, 900.0, 20.0]])
    assert associate(cost, cost <= 100) == {0: 0, 2: 1}
    assert associate(cost, cost <= 1) == {}


def test_a_conflict_takes_the_least_total_cost():
    # both tracks gate both detections: the cheaper total pairs them crosswise
    cost = np.array([[10.0, 12.0], [11.0, 30.0]])
    assert associate(cost, cost <= 50) == {1: 0, 0: 1}
