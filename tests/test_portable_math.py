"""Portable numerics: the elementary functions of fuzzynav.numerics.portable_math and the rule that the simulation
path calls nothing whose last bits depend on the CPU (see README "Numerics")."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from fuzzynav.numerics import portable_math as pm
from fuzzynav.numerics.portable_random import NormalStream, standard_normal, uniform

ROOT = Path(__file__).resolve().parents[1]
ANGLES = st.floats(-1e4, 1e4, allow_nan=False)
COORDS = st.floats(-1e6, 1e6, allow_nan=False, allow_subnormal=False)


def _ulps(a: float, b: float) -> float:
    return abs(a - b) / math.ulp(max(abs(b), 1e-300))


@given(ANGLES)
def test_sin_cos_match_the_c_library_within_rounding(angle):
    s, c = pm.sin_cos_deg(angle)
    # the reference itself rounds angle·π/180 once: allow that error (|angle| rad · 2^-53) plus a few ulp
    slack = 4e-16 + abs(math.radians(angle)) * 2.3e-16
    assert abs(s - math.sin(math.radians(angle))) <= slack
    assert abs(c - math.cos(math.radians(angle))) <= slack
    assert abs(s * s + c * c - 1.0) < 5e-16


@given(st.lists(ANGLES, min_size=1, max_size=40))
def test_array_forms_give_the_same_bits_as_the_scalar_forms(angles):
    s, c = pm.sin_cos_deg_array(np.array(angles))
    for i, a in enumerate(angles):
        assert (s[i], c[i]) == pm.sin_cos_deg(a)
    ys, xs = np.array(angles), np.array(angles[::-1])
    t = pm.atan2_deg_array(ys, xs)
    for i in range(len(angles)):
        assert t[i] == pm.atan2_deg(float(ys[i]), float(xs[i]))


def test_quadrant_angles_are_exact():
    for k in range(-8, 9):
        s, c = pm.sin_cos_deg(90.0 * k)
        assert (s, c) == [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)][k % 4]
        assert math.copysign(1.0, s) == 1.0 or s != 0.0  # never -0.0 (it would show as "-0.0" in logs)
    assert pm.atan2_deg(1.0, 0.0) == 90.0 and pm.atan2_deg(0.0, -1.0) == 180.0 and pm.atan2_deg(-1.0, 0.0) == -90.0
    assert pm.atan2_deg(0.0, 0.0) == 0.0 and pm.atan2_deg(1.0, 1.0) == 45.0
    assert all(math.isnan(v) for v in pm.sin_cos_deg(math.nan) + pm.sin_cos_deg(math.inf))


@given(COORDS, COORDS)
@example(2.5772737854862746e-10, -748100.0)
def test_atan2_matches_the_c_library(y, x):
    ref = math.degrees(math.atan2(y, x))
    got = pm.atan2_deg(y, x)
    if x == 0.0 and y == 0.0:
        assert got == 0.0
    elif abs(ref) == 180.0:  # -0.0 vs 0.0 on the negative x axis: both name the same direction
        # within the same tolerance: y = 2.6e-10, x = -748100 is 180 - 2e-14 degrees, which the C library rounds
        # to 180.0 and the portable form to 179.99999999999997 (1 ulp)
        assert abs(abs(got) - 180.0) <= 1e-14 * 180.0, (y, x, got, ref)
    else:
        assert abs(got - ref) <= 1e-14 * max(1.0, abs(ref)), (y, x, got, ref)


@given(st.floats(-740.0, 700.0))
def test_exp_within_two_ulp(x):
    assert _ulps(float(pm.exp_array(np.array([x]))[0]), math.exp(x)) <= 2.0


@given(st.floats(1e-300, 1e300))
def test_log_within_two_ulp(x):
    ref = math.log(x)
    got = float(pm.log_array(np.array([x]))[0])
    assert abs(got - ref) <= 2.0 * math.ulp(abs(ref)) or abs(got - ref) < 1e-300


def test_exp_log_special_values():
    e = pm.exp_array(np.array([0.0, -800.0, 800.0, np.nan, -np.inf, np.inf]))
    assert e[0] == 1.0 and e[1] == 0.0 and e[2] == np.inf and np.isnan(e[3]) and e[4] == 0.0 and e[5] == np.inf
    lg = pm.log_array(np.array([1.0, 0.0, -1.0, np.nan, np.inf]))
    assert lg[0] == 0.0 and lg[1] == -np.inf and np.isnan(lg[2]) and np.isnan(lg[3])


@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=200))
def test_fsum_dot_is_correctly_rounded_and_order_free(values):
    a = np.array(values)
    exact = math.fsum(x * x for x in values)
    assert pm.fsum_dot(a, a) == exact
    assert pm.fsum_dot(a[::-1], a[::-1]) == exact


def test_normal_draws_have_the_right_moments_and_repeat_exactly():
    z = 2.0 + 0.5 * standard_normal(np.random.default_rng(3), 200_001)
    assert len(z) == 200_001
    assert abs(z.mean() - 2.0) < 0.005 and abs(z.std() - 0.5) < 0.005
    assert abs(np.mean(np.abs(z - 2.0) > 1.0) - 0.0455) < 0.003  # two-sigma tail mass of a Gaussian
    np.testing.assert_array_equal(z, 2.0 + 0.5 * standard_normal(np.random.default_rng(3), 200_001))
    u = [uniform(np.random.default_rng(4), -3.0, 5.0) for _ in range(3)]
    assert all(-3.0 <= v < 5.0 for v in u) and u[0] == u[1] == u[2]


@given(st.lists(st.integers(0, 5000), max_size=12))
@settings(max_examples=25, deadline=None)
def test_normal_stream_gives_the_same_values_whatever_the_request_sizes(sizes):
    chunked = NormalStream(np.random.default_rng(9))
    got = np.concatenate([chunked.draw(0.0, 1.0, n) for n in sizes] + [np.zeros(0)])
    whole = NormalStream(np.random.default_rng(9)).draw(0.0, 1.0, sum(sizes))
    np.testing.assert_array_equal(got, whole)


# -- the rule: nothing on the simulation path computes with a CPU-dependent routine ---------------------
# Everything called per step (sensors, tracking, fuzzy evaluation, TPT, planner, kinematics, contacts),
# the scenario generators and the log writer. fuzzy_reference.py is scikit-fuzzy, used by tests and the
# bench only; portable_math.py is where the replacements live.
SIMULATION_PATH = [*sorted(p for p in (ROOT / "fuzzynav").rglob("*.py")  # every subpackage
                          if p.name not in {"portable_math.py", "fuzzy_reference.py"}),
                   ROOT / "runners" / "logs" / "mcap_log.py"]


def test_the_simulation_path_is_the_whole_simulator():
    """The rule above reads every module of fuzzynav's subpackages (a flat glob would miss them)."""
    names = {p.relative_to(ROOT / "fuzzynav").as_posix() for p in SIMULATION_PATH if p.is_relative_to(ROOT /
    "fuzzynav")}
    assert {"episode.py", "sensing/laser.py", "planning/tpt.py", "pedestrians/social_force.py",
            "policies/dwa.py", "numerics/geometry.py", "scenarios/generators/crowds.py"} <= names
    assert all(p.is_file() for p in SIMULATION_PATH)
FORBIDDEN_NUMPY = {"sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "hypot", "sinh", "cosh", "tanh",
                   "exp", "exp2", "expm1", "log", "log2", "log10", "log1p", "power", "float_power", "cbrt",
                   "dot", "vdot", "inner", "outer", "matmul", "einsum", "tensordot", "linalg", "radians",
                   "degrees", "deg2rad", "rad2deg", "trapezoid", "trapz", "polyval", "polyfit", "convolve"}
FORBIDDEN_MATH = {"sin", "cos", "tan", "asin", "acos", "atan", "atan2", "hypot", "dist", "exp", "exp2", "expm1",
                  "log", "log2", "log10", "log1p", "pow", "cbrt", "sinh", "cosh", "tanh", "erf", "gamma"}
FORBIDDEN_RANDOM = {"normal", "standard_normal", "uniform", "exponential", "gamma", "beta", "lognormal",
                    "vonmises", "triangular"}


def _violations(path: Path, root: Path = ROOT) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        where = f"{path.relative_to(root)}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult | ast.Pow):
            found.append(f"{where}: operator {type(node.op).__name__} (BLAS for @, the C library's pow for **)")
        elif isinstance(node, ast.Attribute):
            owner = node.value.id if isinstance(node.value, ast.Name) else ""
            forbidden = {"np": FORBIDDEN_NUMPY, "math": FORBIDDEN_MATH, "scipy": {"linalg", "spatial"}}
            if node.attr in forbidden.get(owner, ()):
                found.append(f"{where}: {owner}.{node.attr}")
            elif node.attr in FORBIDDEN_RANDOM:
                found.append(f"{where}: .{node.attr}() draws through the C library (use "
                             "fuzzynav.numerics.portable_random)")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in {"numpy", "math", "scipy"}:
            names = {a.name for a in node.names}
            bad = names & (FORBIDDEN_NUMPY | FORBIDDEN_MATH) if node.module != "scipy.optimize" else \
                names - {"linear_sum_assignment"}
            if bad or node.module.startswith(("numpy.linalg", "scipy.linalg")):
                found.append(f"{where}: from {node.module} import {', '.join(sorted(names))}")
    return found


def test_simulation_path_uses_no_cpu_dependent_routines():
    found = [v for path in SIMULATION_PATH for v in _violations(path)]
    assert not found, "CPU-dependent numerics on the simulation path:\n" + "\n".join(found)


def test_the_scan_finds_what_it_forbids(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import math\nimport numpy as np\nfrom numpy.linalg import norm\n"
                   "a = np.cos(1) + math.hypot(1, 2) + (np.ones(2) @ np.ones(2)) + 2.0 ** 0.5\n"
                   "b = np.linalg.norm([1, 2]); c = rng.normal(0, 1)\n")
    found = _violations(bad, root=tmp_path)
    kinds = " ".join(found)
    for expected in ("np.cos", "math.hypot", "MatMult", "Pow", "np.linalg", ".normal()", "numpy.linalg"):
        assert expected in kinds, (expected, found)


@settings(max_examples=30, deadline=None)
@given(st.floats(-360, 360), st.floats(0, 1), st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
def test_portable_functions_ignore_numpy_simd_and_blas(angle, frac, x, y):
    """Same bits whether computed on one element or inside a long (SIMD-processed) array."""
    long = np.full(1031, angle)
    long[517] = angle + frac
    s, c = pm.sin_cos_deg_array(long)
    assert (s[517], c[517]) == pm.sin_cos_deg(angle + frac)
    assert (s[0], c[0]) == pm.sin_cos_deg(angle)
    ys, xs = np.full(1031, y), np.full(1031, x)
    assert pm.atan2_deg_array(ys, xs)[1030] == pm.atan2_deg(y, x)
