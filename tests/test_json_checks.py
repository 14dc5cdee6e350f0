"""analysis.json_checks: the one-pass batch forms (lists of numbers, [x, y] pairs, booleans, objects' fields, TPT
tables) answer exactly as the item-by-item rules do, on values of every JSON type and on what decoded JSON cannot
hold (NaN anywhere, tuples inside, subclasses of int and float, huge ints)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis import json_checks
from analysis.json_checks import MAX_CM, CheckError, are_booleans, are_points, number


class Floaty(float):
    pass


class Inty(int):
    pass


scalars = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False), st.integers(), st.integers(-10**30, 10**30),
    st.sampled_from([0.0, -0.0, 1e9, -1e9, 1e9 + 1, 10**9, 10**9 + 1, 10**400, True, False, None, "1"]),
    st.builds(Floaty, st.floats(-10, 10)), st.builds(Inty, st.integers(-10, 10)))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                        st.tuples(inner, inner)), max_leaves=6)
bounds = st.sampled_from([(-MAX_CM, MAX_CM), (0.0, 180.0), (0.0, MAX_CM), (1e-9, MAX_CM), (-1.0, -1.0)])


def _ok(rule, x) -> bool:
    try:
        rule(x)
    except CheckError:
        return False
    return True


@given(st.lists(values, max_size=12), bounds)
@settings(max_examples=400, deadline=None)
def test_a_number_lists_batch_is_the_item_rule(items, lohi):
    lo, hi = lohi
    rule = number(lo, hi)
    assert json_checks.accepts_all(rule, items) == all(_ok(rule, x) for x in items)


@given(st.lists(st.one_of(st.lists(values, min_size=1, max_size=3), values), max_size=10))
@settings(max_examples=400, deadline=None)
def test_points_are_the_pair_rule(items):
    rule = number(-MAX_CM, MAX_CM)
    expected = all(type(p) is list and len(p) == 2 and all(_ok(rule, x) for x in p) for p in items)
    assert are_points(items) == expected


@given(st.lists(values, max_size=12))
@settings(max_examples=200, deadline=None)
def test_booleans_are_the_type_rule(items):
    assert are_booleans(items) == all(type(x) is bool for x in items)


@given(st.lists(st.floats(-10, 10), min_size=1, max_size=6), st.data())
@settings(max_examples=200, deadline=None)
def test_a_nan_anywhere_is_refused(values, data):
    """min and max skip a NaN that is not first; the batch forms must still refuse it wherever it sits (a number
    list, an object's grouped number fields, point pairs)."""
    values.insert(data.draw(st.integers(0, len(values))), math.nan)
    rule = json_checks.obj(x_cm=number(), y_cm=number())
    assert not json_checks.accepts_all(number(), values)
    assert not json_checks.accepts_all(rule, [{"x_cm": 0.0, "y_cm": v} for v in values])
    assert not are_points([[v, 0.0] for v in values])


objects = st.lists(st.fixed_dictionaries({}, optional={
    "step": st.one_of(st.integers(-2, 10), st.floats(0, 2), st.booleans()), "x_cm": scalars, "y_cm": scalars,
    "flag": st.one_of(st.booleans(), st.integers(0, 1)), "name": st.one_of(st.text(max_size=2), st.none()),
    "angle": st.one_of(st.floats(-10, 200), st.integers(-1, 181)), "items": st.lists(scalars, max_size=2)}),
    max_size=5)


@given(objects)
@settings(max_examples=600, deadline=None)
def test_an_objects_batch_is_its_rule_object_by_object(msgs):
    rule = json_checks.obj(step=json_checks.integer(), x_cm=number(), y_cm=number(), flag=json_checks.boolean,
                           name=json_checks.string, angle=number(0.0, 180.0), items=json_checks.array(number()))
    assert json_checks.accepts_all(rule, msgs) == all(_ok(rule, m) for m in msgs)


def test_tables_of_pairs_and_of_booleans():
    table = [[[1.0, 2], [3.5, -4.0]], [[0, 0], [1e9, -1e9]]]
    assert json_checks.are_tables([table], [2], [2])
    assert json_checks.are_tables([[[True, False], [False, False]]], [2], [2], booleans=True)
    for bad in ([1.0, True], [1.0, 1e9 + 1], [1.0], [1.0, 2.0, 3.0], (1.0, 2.0), [1.0, math.nan]):
        assert not json_checks.are_tables([[[bad, [0.0, 0.0]], [[0, 0], [0, 0]]]], [2], [2]), bad
    assert not json_checks.are_tables([[[True, 1]]], [1], [2], booleans=True)
    assert not json_checks.are_tables([table], [2.0], [2])  # a row count that is not an int
    with pytest.raises(ValueError):
        json_checks.are_tables([table], [2, 2], [2])


def test_tables_without_obstacle_columns_read_as_empty_arrays():
    from analysis.tpt_errors import _table_pairs

    for tabs, rows in (([], 0), ([[[]]], 1), ([[[], []], [[]]], 3)):
        assert _table_pairs(tabs, 0).shape == (rows, 0, 2)
    rule = json_checks.obj(a=number(0, 2**53 + 1), b=number(0, 2**53 + 1))
    assert json_checks.accepts_all(rule, [{"a": 2**53 + 1, "b": 1.0}]) is False  # the bound is its float
