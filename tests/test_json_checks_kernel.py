"""The compiled array tests (fuzzynav._json_checks) answer as the item-by-item rules of analysis.json_checks do,
on values of every JSON type and on what decoded JSON cannot hold (NaN, infinities, tuples inside, subclasses of
int and float, huge ints); and the batch checks of whole episodes give the same answers with the kernel switched
off. In CI (CI=true) the kernel must have been built."""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis import json_checks
from analysis.json_checks import MAX_CM, CheckError, are_booleans, are_points, number
from tests.conftest import require_compiled

kernel = json_checks._kernel
require_compiled(kernel, "_json_checks")


class Floaty(float):
    pass


class Inty(int):
    pass


scalars = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(), st.integers(-10**30, 10**30),
    st.sampled_from([0.0, -0.0, 1e9, -1e9, 1e9 + 1, 10**9, 10**9 + 1, 10**400, True, False, None, "1", math.nan]),
    st.builds(Floaty, st.floats(-10, 10)), st.builds(Inty, st.integers(-10, 10)))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                        st.tuples(inner, inner)), max_leaves=6)
bounds = st.sampled_from([(-MAX_CM, MAX_CM), (0.0, 180.0), (0.0, MAX_CM), (1e-9, MAX_CM), (-1.0, -1.0),
                          (0.0, math.inf), (-math.inf, math.inf)])


def _number_ok(x, lo, hi) -> bool:
    try:
        number(lo, hi)(x)
    except CheckError:
        return False
    return True


@given(st.lists(values, max_size=12), bounds)
@settings(max_examples=400, deadline=None)
def test_numbers_within_is_the_item_rule(items, lohi):
    lo, hi = lohi
    assert kernel.numbers_within(items, lo, hi) == all(_number_ok(x, lo, hi) for x in items)
    assert kernel.numbers_within(tuple(items), lo, hi) == all(_number_ok(x, lo, hi) for x in items)


@given(st.lists(st.one_of(st.lists(values, min_size=1, max_size=3), values), max_size=10))
@settings(max_examples=400, deadline=None)
def test_points_within_is_the_pair_rule(items):
    expected = all(type(p) is list and len(p) == 2 and all(_number_ok(x, -MAX_CM, MAX_CM) for x in p)
                   for p in items)
    assert kernel.points_within(items, -MAX_CM, MAX_CM) == expected


@given(st.lists(values, max_size=12))
@settings(max_examples=200, deadline=None)
def test_all_booleans_is_the_type_rule(items):
    assert kernel.all_booleans(items) == all(type(x) is bool for x in items)


@pytest.mark.parametrize("bad", [None, "ab", {1: 2}, iter([1.0]), 3.0])
def test_what_is_not_a_list_or_tuple_is_not_accepted(bad):
    assert not kernel.numbers_within(bad, 0.0, 1.0)
    assert not kernel.points_within(bad, 0.0, 1.0)
    assert not kernel.all_booleans(bad)


def test_bounds_must_be_floats():
    with pytest.raises(TypeError):
        kernel.numbers_within([1.0], 0, 1.0)


@given(st.lists(st.lists(st.one_of(st.floats(-2e9, 2e9), st.integers(-2 * 10**9, 2 * 10**9), st.booleans()),
                         min_size=2, max_size=2), max_size=8))
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_the_python_forms_agree_without_the_kernel(monkeypatch, pairs):
    """Where decoded JSON can be (no NaN), the Python forms answer as the kernel."""
    with_kernel = (are_points(pairs), are_booleans([x for p in pairs for x in p]))
    with monkeypatch.context() as m:
        m.setenv("FUZZYNAV_KERNEL", "python")
        assert (are_points(pairs), are_booleans([x for p in pairs for x in p])) == with_kernel


def test_whole_episodes_are_accepted_alike_with_the_kernel_switched_off(monkeypatch):
    """The metrics of real logs (TPT tables, decisions, states) with and without the kernel."""
    from pathlib import Path

    from analysis.metrics import metrics_table
    from tests.conftest import ROOT

    logs = sorted(str(p) for p in Path(ROOT, "datasets").rglob("*.mcap"))[:6]
    assert logs
    on, bad_on = metrics_table(logs)
    monkeypatch.setenv("FUZZYNAV_KERNEL", "python")
    off, bad_off = metrics_table(logs)
    columns = [c for c in on.columns if not c.startswith("compute_time")]
    assert bad_on.empty and bad_off.empty
    assert on[columns].equals(off[columns])

