"""The compiled kernel (fuzzynav._mamdani) gives the Python path's bits on every definition and input.

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

from fuzzynav import fuzzy_fast
from fuzzynav.fuzzy_fast import FastEvaluator, kernel_available
from fuzzynav.fuzzy_spec import SOURCES, ControllerSpec, ControllerSpecError

if fuzzy_fast._mamdani is None:
    if os.environ.get("CI"):
        pytest.fail("fuzzynav._mamdani was not built (pip install -e . compiles it; a C compiler is needed)",
                    pytrace=False)
    pytest.skip("fuzzynav._mamdani not built (no C compiler at install): the Python path runs alone",
                allow_module_level=True)


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
    assert ev.uses_kernel, "every definition of at most 63 rules with a finite grid goes through the kernel"
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
            "from fuzzynav.fuzzy_fast import FastEvaluator, kernel_available\n"
            "from fuzzynav.fuzzy_spec import ControllerSpec\n"
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
