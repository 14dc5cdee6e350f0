"""The compiled array tests (analysis._json_checks) answer as the item-by-item rules of analysis.json_checks do,
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


@given(st.lists(st.floats(-10, 10), min_size=1, max_size=6), st.data())
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_a_nan_anywhere_is_refused_with_and_without_the_kernel(monkeypatch, values, data):
    """min and max skip a NaN that is not first; both forms must still refuse it wherever it sits (a number
    list, an object's grouped number fields, point pairs)."""
    values.insert(data.draw(st.integers(0, len(values))), math.nan)
    rule = json_checks.obj(x_cm=number(), y_cm=number())
    pairs = [[v, 0.0] for v in values]
    objects = [{"x_cm": 0.0, "y_cm": v} for v in values]
    for form in (lambda f, *a: f(*a), lambda f, *a: _python(monkeypatch, f, *a)):
        assert not form(json_checks.accepts_all, number(), values)
        assert not form(json_checks.accepts_all, rule, objects)
        assert not form(are_points, pairs)


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



# -- whole TPT tables, object fields, and reading the tables' coordinates -------------------------------------
cells = st.one_of(st.lists(st.one_of(st.floats(-2e9, 2e9), st.integers(-2 * 10**9, 2 * 10**9), st.booleans(),
                                     st.none()), min_size=1, max_size=3),
                  st.booleans(), st.floats(-1, 1), st.none(), st.tuples(st.floats(-1, 1), st.floats(-1, 1)))
tables = st.lists(st.one_of(st.lists(st.lists(cells, max_size=3), max_size=3), st.none(), st.integers(0, 3)),
                  max_size=4)
row_counts = st.one_of(st.integers(-1, 3), st.sampled_from([1.0, True, 2.0, None]))


def _python(monkeypatch, f, *args):
    with monkeypatch.context() as m:
        m.setenv("FUZZYNAV_KERNEL", "python")
        return f(*args)


def _outcome(f, *args):
    """f's answer, or the type of the exception it raised."""
    try:
        return f(*args)
    except (TypeError, ValueError) as err:
        return type(err)


column_counts = st.one_of(st.integers(-1, 3), st.sampled_from([1.0, True, 2.0, None, 2**70]))


@given(tables, st.data())
@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_are_tables_answers_as_the_python_form(monkeypatch, tabs, data):
    """Tables of every shape and cell type (a row or column count that is not an int or is negative, rows of other
    lengths, pairs of three, booleans among coordinates; count lists of another length, tuples) get the same answer
    — or the same error — from the kernel as from the Python form."""
    rows = [len(t) if isinstance(t, list) and data.draw(st.booleans()) else data.draw(row_counts) for t in tabs]
    ks = [len(t[0]) if isinstance(t, list) and t and isinstance(t[0], list) and data.draw(st.booleans())
          else data.draw(column_counts) for t in tabs]
    shape = data.draw(st.sampled_from(["same", "rows short", "ks long", "tuple"]))
    if shape == "rows short":
        rows = rows[:-1]
    elif shape == "ks long":
        ks = [*ks, 1]
    elif shape == "tuple":
        tabs = tuple(tabs)
    for booleans in (False, True):
        expected = _python(monkeypatch, _outcome, json_checks.are_tables, tabs, rows, ks, booleans)
        assert _outcome(json_checks.are_tables, tabs, rows, ks, booleans) == expected


def test_are_tables_accepts_real_tables_and_refuses_one_bad_cell():
    table = [[[1.0, 2], [3.5, -4.0]], [[0, 0], [1e9, -1e9]]]
    assert kernel.tables_within([table], [2], [2], -MAX_CM, MAX_CM)
    assert kernel.tables_booleans([[[True, False], [False, False]]], [2], [2])
    for bad in ([1.0, True], [1.0, 1e9 + 1], [1.0], [1.0, 2.0, 3.0], (1.0, 2.0), [1.0, math.nan]):
        assert not kernel.tables_within([[[bad, [0.0, 0.0]], [[0, 0], [0, 0]]]], [2], [2], -MAX_CM, MAX_CM), bad
    assert not kernel.tables_booleans([[[True, 1]]], [1], [2])
    assert not kernel.tables_within([table], [2.0], [2], -MAX_CM, MAX_CM)  # a row count that is not an int
    with pytest.raises(ValueError):
        kernel.tables_within([table], [2, 2], [2], -MAX_CM, MAX_CM)


@given(st.lists(st.lists(st.lists(st.lists(st.one_of(st.floats(allow_nan=False), st.integers(-10**20, 10**20)),
                                           min_size=2, max_size=2), min_size=2, max_size=2), max_size=4),
                max_size=5))
@settings(max_examples=300, deadline=None)
def test_table_pairs_reads_the_numbers_numpy_reads(tabs):
    import numpy as np

    from analysis.tpt_errors import _pairs

    got = np.frombuffer(kernel.table_pairs(tabs, 2))
    expected = _pairs([row for t in tabs for row in t], 2).reshape(-1)
    assert np.array_equal(got, expected)
    assert got.tobytes() == expected.tobytes()  # -0.0 and the rounding of big ints included


@pytest.mark.parametrize(("tabs", "error"), [
    ([[[[1.0, 2.0]]], [[[1.0, 2.0], [3.0, 4.0]]]], ValueError),  # a row of another length
    ([[[[1.0, 2.0, 3.0]]]], ValueError), ([[[[1.0]]]], ValueError),  # a pair of three, of one
    ([[[(1.0, 2.0)]]], TypeError), ([[((1.0, 2.0),)]], TypeError), ([(([1.0, 2.0],),)], TypeError),
    ([[[[True, 2.0]]]], TypeError), ([[[["1", 2.0]]]], TypeError), ([[[[10**400, 2.0]]]], OverflowError)])
def test_table_pairs_refuses_what_is_not_a_table_of_pairs(tabs, error):
    with pytest.raises(error):
        kernel.table_pairs(tabs, 1)


kinds = st.sampled_from([(0, -MAX_CM, MAX_CM), (0, 0.0, 180.0), (1, 0, 2**63 - 1), (1, 1, 1_000_000), (2, None, None),
                         (3, None, None)])
field_values = st.one_of(scalars, st.text(max_size=3), st.lists(scalars, max_size=2))
messages = st.lists(st.one_of(st.dictionaries(st.sampled_from(["a", "b", "c"]), field_values, max_size=3),
                              st.none(), st.lists(scalars, max_size=1)), max_size=6)


@given(messages, st.lists(st.sampled_from(["a", "b", "c"]), min_size=1, max_size=3, unique=True), kinds)
@settings(max_examples=600, deadline=None)
def test_fields_within_is_the_field_rule(msgs, names, kind):
    """Each kind answers as its item rule (number, integer, boolean, string) on every field of every object; an
    object without a field, or that is not a dict, is refused."""
    code, lo, hi = kind
    rule = {0: lambda: number(lo, hi), 1: lambda: json_checks.integer(lo, hi), 2: lambda: json_checks.boolean,
            3: lambda: json_checks.string}[code]()

    def ok(v):
        try:
            rule(v)
        except CheckError:
            return False
        return True

    expected = all(type(m) is dict and all(n in m and ok(m[n]) for n in names) for m in msgs)
    assert kernel.fields_within(msgs, tuple(names), code, lo, hi) == expected


def test_fields_within_refuses_bad_arguments():
    with pytest.raises(TypeError):
        kernel.fields_within([{}], ("a",), 0, 0, 1.0)  # a number's bounds are floats
    with pytest.raises(TypeError):
        kernel.fields_within([{}], ("a",), 1, 0.0, 1)  # an integer's are ints
    with pytest.raises(TypeError):
        kernel.fields_within([{}], (1,), 2, None, None)  # names are str
    with pytest.raises(ValueError):
        kernel.fields_within([{}], ("a",), 7, None, None)
    assert not kernel.fields_within([DictSubclass(a=True)], ("a",), 2, None, None)


def test_fields_within_takes_exact_types_only():
    """A boolean is not an integer nor a number, a subclass of int, float or str is not one (as the rules say)."""
    assert kernel.fields_within([{"a": 3, "b": 0}], ("a", "b"), 1, 0, 10)
    for bad in (True, Inty(3), 3.0):
        assert not kernel.fields_within([{"a": bad}], ("a",), 1, 0, 10), bad
    for bad in (True, Floaty(1.0), Inty(1)):
        assert not kernel.fields_within([{"a": bad}], ("a",), 0, 0.0, 10.0), bad
    assert kernel.fields_within([{"a": "x"}], ("a",), 3, None, None)
    assert not kernel.fields_within([{"a": type("S", (str,), {})("x")}], ("a",), 3, None, None)
    assert not kernel.fields_within([{"a": 1}], ("a",), 2, None, None)
    assert not kernel.fields_within([{"a": 11}], ("a",), 1, 0, 10)
    assert not kernel.fields_within([{"a": 1}, {"b": 1}], ("a",), 1, 0, 10)  # a missing field


class DictSubclass(dict):
    pass


objects = st.lists(st.fixed_dictionaries({}, optional={
    "step": st.one_of(st.integers(-2, 10), st.floats(0, 2), st.booleans()), "x_cm": st.one_of(scalars),
    "y_cm": scalars, "flag": st.one_of(st.booleans(), st.integers(0, 1)), "name": st.one_of(st.text(max_size=2),
                                                                                        st.none()),
    "angle": st.one_of(st.floats(-10, 200), st.integers(-1, 181)), "items": st.lists(scalars, max_size=2)}),
    max_size=5)


@given(objects)
@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_an_objects_batch_check_answers_alike_with_and_without_the_kernel(monkeypatch, msgs):
    """obj()'s batch form (every scalar field by kind in the kernel) accepts exactly what its Python form accepts."""
    rule = json_checks.obj(step=json_checks.integer(), x_cm=number(), y_cm=number(), flag=json_checks.boolean,
                           name=json_checks.string, angle=number(0.0, 180.0), items=json_checks.array(number()))
    assert json_checks.accepts_all(rule, msgs) == _python(monkeypatch, json_checks.accepts_all, rule, msgs)


def test_edge_arguments_answer_alike_with_and_without_the_kernel(monkeypatch):
    """No obstacle column (k = 0) gives an empty (rows, 0, 2) array on both paths; an int bound beyond 2**53 means
    its float on both (the kernel takes float bounds)."""
    from analysis.tpt_errors import _table_pairs

    for tabs, rows in (([], 0), ([[[]]], 1), ([[[], []], [[]]], 3)):
        for got in (_table_pairs(tabs, 0), _python(monkeypatch, _table_pairs, tabs, 0)):
            assert got.shape == (rows, 0, 2)
    rule = json_checks.obj(a=number(0, 2**53 + 1), b=number(0, 2**53 + 1))
    values = [{"a": 2**53 + 1, "b": 1.0}]
    assert json_checks.accepts_all(rule, values) is False
    assert _python(monkeypatch, json_checks.accepts_all, rule, values) is False
    assert _python(monkeypatch, json_checks.accepts_all, number(0, 2**53 + 1), [2**53 + 1]) is False
