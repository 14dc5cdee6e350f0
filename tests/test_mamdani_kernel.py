"""The compiled kernel (fuzzynav.controller._mamdani) gives the Python path's bits on every definition and input.

The Python path (``FastEvaluator._evaluate_scalar``) is the definition and the fallback when the kernel is not
built; the recorded datasets hash every decision, so the two must agree bit for bit, on inputs and definitions
neither was written for: random controller definitions (fuzzy and crisp inputs, tri/trap/gauss terms, rules
naming any subset of inputs and one or both outputs, narrow and wide universes) and random inputs (grid
points, universe edges, outside the universe, ints, infinities, NaN). In CI (CI=true) the kernel must have been
built: a silently missing build would leave these tests skipped.
"""

from __future__ import annotations

import contextlib
import math
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fuzzynav.controller import fuzzy_fast
from fuzzynav.controller.fuzzy_fast import FastEvaluator, kernel_available
from fuzzynav.controller.fuzzy_spec import SOURCES, ControllerSpec, ControllerSpecError
from tests.conftest import require_compiled

require_compiled(fuzzy_fast._mamdani, "_mamdani")


def _bits(result) -> bytes:
    return struct.pack("<dd", *result)


def _both(ev: FastEvaluator, inputs: dict) -> tuple:
    """(kernel outcome, Python path outcome): the bits, or the exception's type and message."""
    outcomes = []
    for call in (lambda: ev._kernel.decide(inputs), lambda: ev._evaluate_scalar(inputs)):
        try:
            outcomes.append(_bits(call()))
        except Exception as exc:  # both paths must raise the same error
            outcomes.append((type(exc), str(exc)))
    return tuple(outcomes)


@st.composite
def universes(draw, lo_range=(-500.0, 500.0), width_range=(1.0, 1000.0)):
    resolution = draw(st.sampled_from([0.05, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0]))
    steps = draw(st.integers(2, min(600, int(width_range[1] / resolution))))
    assume(width_range[0] <= steps * resolution <= width_range[1])
    lo = draw(st.floats(*lo_range, allow_nan=False)) if lo_range[0] < lo_range[1] else lo_range[0]
    lo = round(lo / resolution) * resolution
    return lo, lo + steps * resolution, resolution


@st.composite
def terms(draw, lo, hi, resolution, crisp):
    n = draw(st.integers(1, 5))
    out = {}
    if crisp:
        cuts = sorted(draw(st.lists(st.floats(lo, hi), min_size=n - 1, max_size=n - 1)))
        edges = [lo, *cuts, hi]
        for i in range(n):
            if edges[i] < edges[i + 1]:
                out[f"c{i}"] = {"mf": "crisp", "params": [edges[i], edges[i + 1]]}
        assume(out)
        return out
    span = hi - lo
    for i in range(n):
        kind = draw(st.sampled_from(["tri", "trap", "gauss"]))
        point = st.floats(lo - 0.2 * span, hi + 0.2 * span, allow_nan=False)
        if kind == "gauss":
            out[f"t{i}"] = {"mf": "gauss", "params": [draw(point), draw(st.floats(resolution, span))]}
            continue
        # on the grid sometimes: a breakpoint on a grid point is where interpolation and crossings are exact
        params = sorted(draw(st.one_of(point, st.integers(0, round(span / resolution)).map(
            lambda k: lo + k * resolution))) for _ in range(3 if kind == "tri" else 4))
        out[f"t{i}"] = {"mf": kind, "params": params}
    return out


@st.composite
def controllers(draw) -> ControllerSpec:
    sources = draw(st.lists(st.sampled_from(SOURCES), min_size=1, max_size=4, unique=True))
    inputs = {}
    for i, source in enumerate(sources):
        lo, hi, res = draw(universes())
        crisp = draw(st.booleans()) and i > 0
        inputs[f"in{i}"] = {"source": source, "universe": [lo, hi], "resolution": res,
                            "terms": draw(terms(lo, hi, res, crisp))}
    d_lo, d_hi, d_res = draw(universes(lo_range=(-180.0, 0.0), width_range=(1.0, 180.0)))
    v_lo, v_hi, v_res = draw(universes(lo_range=(0.0, 60.0), width_range=(1.0, 200.0)))
    outputs = {"dtheta": {"universe": [d_lo, d_hi], "resolution": d_res,
                          "terms": draw(terms(d_lo, d_hi, d_res, False))},
               "v": {"universe": [v_lo, v_hi], "resolution": v_res, "terms": draw(terms(v_lo, v_hi, v_res, False))}}
    rules = []
    for _ in range(draw(st.integers(1, 40))):
        names = draw(st.lists(st.sampled_from(sorted(inputs)), min_size=1, max_size=len(inputs), unique=True))
        ante = " & ".join(f"{n}={draw(st.sampled_from(sorted(inputs[n]['terms'])))}" for n in names)
        outs = draw(st.sampled_from([("dtheta",), ("v",), ("dtheta", "v")]))
        cons = ", ".join(f"{o}={draw(st.sampled_from(sorted(outputs[o]['terms'])))}" for o in outs)
        rules.append(f"{ante} -> {cons}")
    data = {"inputs": inputs, "outputs": outputs, "rules": rules,
            "fallback": {"dtheta": draw(st.floats(d_lo, d_hi)), "v": draw(st.floats(v_lo, v_hi))}}
    try:
        return ControllerSpec.from_dict(data)
    except ControllerSpecError:
        assume(False)


def _values(spec: ControllerSpec, rng: np.random.Generator, n: int) -> list[dict]:
    """n input dicts: uniform over each universe widened by 20 %, a third on grid points and term breakpoints,
    some exactly on the universe edges, outside it, ints and infinities."""
    columns = {}
    for var in spec.inputs:
        lo, hi = var.universe
        special = [lo, hi, lo - 1.0, hi + 1.0, math.inf, -math.inf, 0.0, -0.0]
        special += [p for t in var.terms for p in t.params]
        special += list(var.grid[rng.integers(0, len(var.grid), 8)])
        x = list(rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), n))
        for i in range(0, n, 3):
            x[i] = float(special[rng.integers(0, len(special))])
        for i in range(1, n, 11):
            x[i] = round(x[i]) if math.isfinite(x[i]) else x[i]  # an int where it is finite
        columns[var.name] = x
    return [{k: c[i] for k, c in columns.items()} for i in range(n)]


@given(controllers(), st.integers(0, 2**32 - 1))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
def test_kernel_gives_the_python_paths_bits_on_random_definitions(spec, seed):
    ev = FastEvaluator(spec)
    # every definition of at most 63 rules with a finite grid goes through the kernel, but for one whose sampled
    # output memberships hold a -0.0 (a breakpoint given as -0.0 on a grid point): the Python path takes it
    assert ev.uses_kernel or np.signbit(ev._stacked_mfs).any()
    assume(ev.uses_kernel)
    for inputs in _values(spec, np.random.default_rng(seed), 60):
        kernel, python = _both(ev, inputs)
        assert kernel == python, (inputs, kernel, python)


@pytest.mark.parametrize("name", ["table1", "listing"])
def test_kernel_gives_the_python_paths_bits_on_the_shipped_controllers(name, table1, listing):
    spec = {"table1": table1, "listing": listing}[name]
    ev = FastEvaluator(spec)
    assert ev.uses_kernel
    for inputs in _values(spec, np.random.default_rng(5), 5_000):
        kernel, python = _both(ev, inputs)
        assert kernel == python, (inputs, kernel, python)


def test_a_nan_input_raises_as_the_python_path_does(table1):
    ev = FastEvaluator(table1)
    inputs = {"left": 50.0, "front": math.nan, "right": 50.0, "angle": 0.0}
    with pytest.raises(ValueError, match="NaN"):
        ev.evaluate(inputs)
    assert _both(ev, inputs)[0] == _both(ev, inputs)[1]


def test_what_the_kernel_does_not_take_goes_to_the_python_path(table1):
    ev = FastEvaluator(table1)
    one = {"left": 40.0, "front": 70.0, "right": 100.0, "angle": -30.0}
    assert ev._kernel.decide(dict(one, extra=np.zeros(3))) is None  # an array anywhere: the batch
    assert ev._kernel.decide(list(one.items())) is None  # not a dict
    with pytest.raises(KeyError, match="angle"):
        ev.evaluate({k: v for k, v in one.items() if k != "angle"})
    with pytest.raises(OverflowError):
        ev.evaluate(dict(one, left=10**400))

    class Inputs(dict):
        pass

    assert _bits(ev.evaluate(Inputs(one))) == _bits(ev._evaluate_scalar(one))  # a dict subclass: Python path
    assert _bits(ev.evaluate(dict(one, left=np.float64(40.0)))) == _bits(ev._evaluate_scalar(one))


def test_a_batch_gives_the_single_decisions_bits_and_nan_rows_take_the_numpy_batch(table1):
    ev = FastEvaluator(table1)
    rng = np.random.default_rng(2)
    cols = {v.name: rng.uniform(v.universe[0] - 10, v.universe[1] + 10, 500) for v in table1.inputs}
    d, v = ev.evaluate(cols)
    for i in range(500):
        assert _bits((d[i], v[i])) == _bits(ev._evaluate_scalar({k: float(c[i]) for k, c in cols.items()}))
    cols["front"][7] = math.nan
    d, v = ev.evaluate(cols)  # the numpy batch: NaN in, NaN out, the other rows within 1e-9
    assert d.shape == (500,) and np.isfinite(np.delete(d, 7)).all()
    one = ev.evaluate({k: c[3] for k, c in cols.items()})
    assert abs(d[3] - one[0]) <= 1e-9 and abs(v[3] - one[1]) <= 1e-9


def test_definitions_over_63_rules_use_the_python_path():
    terms = {f"t{i}": {"mf": "tri", "params": [10 * i, 10 * i + 5, 10 * i + 10]} for i in range(8)}
    data = {"inputs": {"front": {"source": "front", "universe": [0, 80], "terms": terms},
                       "left": {"source": "left", "universe": [0, 80], "terms": terms}},
            "outputs": {"dtheta": {"universe": [-10, 10], "terms": {"z": {"mf": "tri", "params": [-10, 0, 10]}}},
                        "v": {"universe": [10, 40], "terms": {"s": {"mf": "tri", "params": [10, 20, 30]}}}},
            "rules": [f"front=t{i} & left=t{j} -> dtheta=z, v=s" for i in range(8) for j in range(8)]}
    ev = FastEvaluator(ControllerSpec.from_dict(data))
    assert len(ev.spec.rules) == 64 and not ev.uses_kernel
    assert ev.evaluate({"front": 42.5, "left": 3.0}) == ev._evaluate_scalar({"front": 42.5, "left": 3.0})


def test_the_environment_switches_the_kernel_off():
    code = ("import yaml\n"
            "from fuzzynav.controller.fuzzy_fast import FastEvaluator, kernel_available\n"
            "from fuzzynav.controller.fuzzy_spec import ControllerSpec\n"
            "spec = ControllerSpec.from_dict(yaml.safe_load(open('conf/controller/table1.yaml')))\n"
            "print(kernel_available(), FastEvaluator(spec).uses_kernel)")
    env = dict(os.environ, FUZZYNAV_KERNEL="python")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                         cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.split() == ["False", "False"], out.stderr
    assert kernel_available()


@given(st.integers(0, 16), st.integers(0, 10**6), st.integers(-3, 2**41), st.booleans())
@settings(max_examples=300, deadline=None)
def test_broken_tables_are_refused_not_followed(table1, which, position, value, truncate):
    """The kernel follows indices from its tables: any table that would send it outside its arrays is
    refused with ValueError when it is made, and one it accepts evaluates without leaving them."""
    names, sizes, tables, scalars = FastEvaluator(table1)._kernel_tables()
    raw = bytearray(tables[which])
    if truncate or not raw:
        raw = raw[: len(raw) // 2]
    else:
        at = (position % (len(raw) // 8)) * 8
        raw[at:at + 8] = struct.pack("=q", value) if which in (1, 2, 3, 5, 7, 8, 9, 12, 13) else \
            struct.pack("=d", float(value))
    broken = (*tables[:which], bytes(raw), *tables[which + 1:])
    try:
        kernel = fuzzy_fast._mamdani.Kernel(names, sizes, broken, scalars)
    except ValueError:
        return
    for inputs in _values(table1, np.random.default_rng(position), 20):
        with contextlib.suppress(ValueError, OverflowError, SystemError):  # refused is fine; a crash is not
            kernel.decide(inputs)


@given(st.integers(0, 13), st.integers(-3, 2**41))
@settings(max_examples=200, deadline=None)
def test_broken_sizes_are_refused_or_stay_inside(table1, which, value):
    names, sizes, tables, scalars = FastEvaluator(table1)._kernel_tables()
    values = list(struct.unpack(f"={len(sizes) // 8}q", sizes))
    values[which] = value
    try:
        kernel = fuzzy_fast._mamdani.Kernel(names, struct.pack(f"={len(values)}q", *values), tables, scalars)
    except ValueError:
        return
    for inputs in _values(table1, np.random.default_rng(value % 1000), 20):
        with contextlib.suppress(ValueError, OverflowError, SystemError):  # refused is fine; a crash is not
            kernel.decide(inputs)


def test_a_kernel_that_was_not_made_refuses_to_run():
    kernel = fuzzy_fast._mamdani.Kernel.__new__(fuzzy_fast._mamdani.Kernel)
    with pytest.raises(ValueError, match="not initialised"):
        kernel.decide({"x": 1.0})
    with pytest.raises((TypeError, ValueError)):
        fuzzy_fast._mamdani.Kernel(("x",), b"", (), b"")


# -- hostile inputs and tables (each test below failed, or crashed the interpreter, before its fix) --------------

_ONE = {"left": 40.0, "front": 70.0, "right": 100.0, "angle": -30.0}


@pytest.mark.parametrize("inputs", [
    {"left": math.nan, "front": 70.0, "right": 100.0},  # NaN, then a missing key: the NaN's ValueError
    {"left": math.nan, "front": 10**400, "right": 100.0, "angle": 0.0},  # NaN, then an int too large for a float
    {"left": 40.0, "front": math.nan, "right": 10**400},
    {"left": 10**400, "front": math.nan},  # the int first: its OverflowError
    {"left": 40.0, "front": 70.0, "right": math.nan, "angle": math.nan},  # a NaN angle (crisp) raises nothing
])
def test_an_input_the_decision_raises_at_is_raised_before_later_inputs_are_read(table1, inputs):
    """The Python path takes the inputs one by one (read, clip, fuzzify): a NaN input raises before the next
    input is even read. The kernel read them all first, so a later missing key or huge int raised instead."""
    kernel, python = _both(FastEvaluator(table1), inputs)
    assert isinstance(python, tuple) and kernel == python


def test_each_value_converts_as_float_does(table1):
    """A float or int subclass is read through float(), as the Python path reads it (its own __float__ included),
    not as the raw float or int inside it."""
    class Reading(float):
        def __float__(self):
            return 5.0

    class Count(int):
        def __float__(self):
            return 5.0

    class Failing(float):
        def __float__(self):
            raise RuntimeError("no reading")

    ev = FastEvaluator(table1)
    base = {"left": 82.80501935178906, "front": 35.07227278930314, "right": 5.326558111705309, "angle": -174.05}
    assert _bits(ev._evaluate_scalar(base)) != _bits(ev._evaluate_scalar(dict(base, left=5.0)))  # left matters
    for value in (Reading(82.8), Count(83), True, False, np.float64(82.8), Failing(82.8)):
        inputs = dict(base, left=value)
        kernel, python = _both(ev, inputs)
        assert kernel == python, (value, kernel, python)
        if not isinstance(value, Failing):
            assert _bits(ev.evaluate(inputs)) == _bits(FastEvaluator(table1, use_kernel=False).evaluate(inputs))


def test_a_kernel_cannot_be_made_again_while_or_after_it_runs(table1):
    """Python code can run in decide (a key's __eq__, a value's __float__). A second __init__ from there freed
    the names and tables the call was using and changed the input count under its buffer (a stack overflow
    with more than 16 inputs): a kernel is made once."""
    names, sizes, tables, scalars = FastEvaluator(table1)._kernel_tables()
    kernel = fuzzy_fast._mamdani.Kernel(names, sizes, tables, scalars)
    with pytest.raises(TypeError, match="already initialised"):
        kernel.__init__(names, sizes, tables, scalars)
    wide = 40  # input 0 of table1 forty times over
    sizes_wide = struct.pack("=14q", wide, *struct.unpack("=14q", sizes)[1:])
    wide_args = (tuple(f"n{i}" for i in range(wide)), sizes_wide, (tables[0][:24] * wide, tables[1][:24] * wide,
                                                                     *tables[2:]), scalars)
    fuzzy_fast._mamdani.Kernel(*wide_args)  # a valid kernel of its own

    class Key(str):
        armed = False

        def __hash__(self):
            return hash("left")

        def __eq__(self, other):
            if Key.armed:
                Key.armed = False
                kernel.__init__(*wide_args)
            return False

    inputs = {Key("k"): 1.0, **_ONE, **{f"n{i}": 50.0 for i in range(wide)}}
    Key.armed = True
    with pytest.raises(TypeError, match="already initialised"):
        kernel.decide(inputs)
    assert _bits(kernel.decide(dict(_ONE))) == _bits(FastEvaluator(table1)._evaluate_scalar(_ONE))


def _tiny_spec() -> ControllerSpec:
    """Two inputs (one crisp), two outputs (tri, trap, gauss terms) on grids of a few points: small tables."""
    def terms(**params):
        return {name: {"mf": {2: "crisp", 3: "tri", 4: "trap"}[len(p)] if name != "R" else "gauss", "params": p}
                for name, p in params.items()}

    return ControllerSpec.from_dict({
        "inputs": {"a": {"source": "front", "universe": [0, 4], "resolution": 1,
                         "terms": terms(n=[0, 0, 2], f=[1, 3, 4, 4])},
                   "b": {"source": "angle", "universe": [-2, 2], "resolution": 1,
                         "terms": terms(l=[-2, 0], r=[0, 2])}},
        "outputs": {"dtheta": {"universe": [-3, 3], "resolution": 1, "terms": terms(L=[-3, -2, 0], R=[1, 1])},
                    "v": {"universe": [0, 4], "resolution": 1, "terms": terms(s=[0, 1, 2], q=[1, 2, 3, 4])}},
        "rules": ["a=n & b=l -> dtheta=L, v=s", "a=f -> dtheta=R", "b=r -> v=q", "a=n -> v=q, dtheta=R"]})


_INT_TABLES = (1, 2, 3, 5, 7, 8, 9, 12, 13)


def test_offsets_near_the_int64_limits_are_refused():
    """An offset and a count were checked as off + count <= rows: with an offset near 2^63 the sum wrapped to a
    negative number and passed, and the kernel read (in_i: and wrote) far outside its arrays (a segfault)."""
    names, sizes, tables, scalars = FastEvaluator(_tiny_spec())._kernel_tables()
    top = 2**63 - 1
    for which, index in [(1, 2), (2, 0), (12, 4), (12, 6), (13, 0), (13, 3)]:  # in_i, seg_i, term_i, fall_start
        raw = bytearray(tables[which])
        raw[8 * index:8 * index + 8] = struct.pack("=q", top)
        with pytest.raises(ValueError, match="out of range"):
            fuzzy_fast._mamdani.Kernel(names, sizes, (*tables[:which], bytes(raw), *tables[which + 1:]), scalars)


def test_every_entry_of_every_table_at_hostile_values_is_refused_or_stays_inside():
    """Every entry of every table of a small definition set to each hostile value: refused when it is made, or
    evaluated without leaving the arrays (a crash here; the sanitizer build sees a stray read)."""
    spec = _tiny_spec()
    names, sizes, tables, scalars = FastEvaluator(spec)._kernel_tables()
    inputs = [{"a": a, "b": b} for a in (-1.0, 0.0, 0.5, 1.0, 2.5, 4.0, 9.0) for b in (-3.0, -1.0, 0.0, 2.0)]
    columns = tuple(np.array([row[n] for row in inputs]) for n in names)
    ints = (2**63 - 1, 2**63 - 2, -2**63, -1, 2**40, 2**40 + 1, 2**62)
    floats = (math.nan, math.inf, -math.inf, -0.0, 1e308, 5e-324)
    for which in range(17):
        for at in range(len(tables[which]) // 8):
            for value in ints if which in _INT_TABLES else floats:
                raw = bytearray(tables[which])
                raw[8 * at:8 * at + 8] = struct.pack("=q" if which in _INT_TABLES else "=d", value)
                try:
                    kernel = fuzzy_fast._mamdani.Kernel(names, sizes, (*tables[:which], bytes(raw),
                                                                       *tables[which + 1:]), scalars)
                except ValueError:
                    continue
                for row in inputs:
                    with contextlib.suppress(ValueError, OverflowError, SystemError):
                        kernel.decide(row)
                with contextlib.suppress(ValueError, OverflowError, SystemError):
                    kernel.fill(columns, np.empty(len(inputs)), np.empty(len(inputs)))


def test_sizes_whose_product_overflows_are_refused_before_it_is_formed(table1):
    """n_out x g (the sampled output memberships) was formed before any check: two sizes of 2^40 made it
    overflow (undefined behaviour, seen by -fsanitize=undefined). Now refused with the sizes."""
    names, sizes, tables, scalars = FastEvaluator(table1)._kernel_tables()
    values = list(struct.unpack("=14q", sizes))
    values[8] = values[10] = 2**40
    with pytest.raises(ValueError, match="inconsistent sizes"):
        fuzzy_fast._mamdani.Kernel(names, struct.pack("=14q", *values), tables, scalars)


def test_one_clause_rules_cap_a_membership_a_hair_above_one():
    """The universe [33.76, 44.46] is 107.00000000000003 steps of 0.1: at its top the interpolation weight is a
    hair over 1 and a term peaking there has a membership a hair over 1.0. The Python path's antecedents are
    padded with the constant 1.0 (min caps it at 1.0); with only one-clause rules the kernel's table was not, so
    the cut went over 1.0, a crossing point at the top of a plateau was dropped, and dtheta differed by an ulp."""
    lo, hi, res = 33.76, 44.46, 0.1
    spec = ControllerSpec.from_dict({
        "inputs": {"a": {"source": "front", "universe": [lo, hi], "resolution": res,
                         "terms": {"top": {"mf": "tri", "params": [hi - 2 * res, hi, hi]},
                                   "low": {"mf": "trap", "params": [lo, lo, lo + res, hi - res]}}}},
        "outputs": {"dtheta": {"universe": [-14.0, 14.7], "resolution": 0.7,
                               "terms": {"z": {"mf": "trap", "params": [-10.8343696738396, -8.8343696738396,
                                                                        9.793044470605444, 11.793044470605444]},
                                         "y": {"mf": "tri", "params": [6.558589467063079, 9.55858946706308,
                                                                       10.657767455327388]}}},
                    "v": {"universe": [0, 10], "resolution": 1, "terms": {"s": {"mf": "tri", "params": [0, 4, 10]}}}},
        "rules": ["a=top -> dtheta=z, v=s", "a=low -> dtheta=y"]})
    ev = FastEvaluator(spec)
    assert ev.uses_kernel and ev._antecedents.shape[1] == 1
    for x in (hi, 1e9, hi - res / 2, lo):
        kernel, python = _both(ev, {"a": x})
        assert kernel == python, (x, kernel, python)
