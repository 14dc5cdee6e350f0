"""Elementary functions whose results are the same bits on every CPU, operating system and build.

Why this module exists: a closed-loop simulation amplifies last-bit differences (one 1e-13 change once
moved 43 of 440 recorded trajectories), and the usual fast routes to these functions are CPU-dependent:

- numpy's ``sin``, ``cos``, ``exp``, ``log``, ``arctan2``, ... switch to SIMD implementations chosen at
  run time (e.g. SVML on AVX-512 CPUs) whose last bits differ from the baseline ones;
- ``@``, ``np.dot``, ``np.linalg`` (even ``np.linalg.norm`` without ``axis``) call OpenBLAS, which picks
  a kernel per CPU (``OPENBLAS_CORETYPE`` shows the differences on one machine);
- the C library's ``sin``/``exp``/... (``math.sin``, numpy's scalar fallbacks) differ between C library
  versions and between the FMA and non-FMA variants glibc selects per CPU; CPython's ``math.hypot`` and
  ``math.dist`` changed between Python versions.

Everything here uses only IEEE-754 basic operations (``+ - * /`` and ``sqrt``, each correctly rounded),
exact operations (``frexp``, ``ldexp``, ``rint``, comparisons, ``math.fsum``) and a fixed evaluation
order, one operation at a time (numpy ufunc calls and Python float operators are never fused into an
FMA). So the same inputs give the same bits on any IEEE-754 machine, x86-64 and ARM64 alike. Accuracy is
a few units in the last place of the exact value (tests compare with ``math``).

Angles are in degrees (the project's unit). Each function exists for Python floats and, with the suffix
``_array``, elementwise for numpy arrays, with bit-identical results (same operations in the same order).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from fractions import Fraction

import numpy as np

RAD_PER_DEG = math.pi / 180.0
DEG_PER_RAD = 180.0 / math.pi
_TAN_PI_8 = math.sqrt(2.0) - 1.0  # tan(22.5°), the split between atan's two reductions
# ln 2 split in two (fdlibm's constants): k * _LN2_HI is exact for |k| < 2**20, which keeps the argument
# reduction of exp and log exact
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.0 / math.log(2.0)  # only chooses k; its last bit does not matter, its value is fixed
_SQRT_HALF = math.sqrt(0.5)


def _series(signs: int, denominators: Iterable[int]) -> tuple[float, ...]:
    """Correctly rounded coefficients (±1)^k / d_k (exact rational arithmetic, then one rounding)."""
    return tuple(float(Fraction((-1) ** (k * signs), d)) for k, d in enumerate(denominators, start=1))


# Taylor coefficients: on the reduced ranges below every series is truncated where the next term is below
# 1e-19 relative to the result
_SIN = _series(1, (math.factorial(2 * k + 1) for k in range(1, 9)))  # x^3 .. x^17, |x| <= pi/4
_COS = _series(1, (math.factorial(2 * k) for k in range(1, 10)))  # x^2 .. x^18, |x| <= pi/4
_ATAN = _series(1, (2 * k + 1 for k in range(1, 13)))  # x^3 .. x^25, |x| <= tan(pi/16)
_ATANH = _series(0, (2 * k + 1 for k in range(1, 12)))  # x^3 .. x^23, |x| <= 0.1716
_EXP = (1.0, 1.0, *(float(Fraction(1, math.factorial(n))) for n in range(2, 17)))  # x^0 .. x^16, |x| <= 0.35


def _horner(z, coefficients: Sequence[float]):
    """c0 + z·(c1 + z·(c2 + ...)), one rounding per operation (floats or arrays alike)."""
    acc = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        acc = acc * z + c
    return acc


def _sin_cos_reduced(x):
    """(sin x, cos x) for |x| <= pi/4 radians."""
    z = x * x
    return x + x * z * _horner(z, _SIN), 1.0 + z * _horner(z, _COS)


def sin_cos_deg(angle_deg: float) -> tuple[float, float]:
    """(sin, cos) of an angle in degrees. Exact at multiples of 90° (cos 90° is 0, not 6e-17)."""
    if not math.isfinite(angle_deg):
        return math.nan, math.nan
    q = round(angle_deg / 90.0)  # nearest quadrant (ties to even, as np.rint)
    s, c = _sin_cos_reduced((angle_deg - 90.0 * q) * RAD_PER_DEG)
    ns, nc = 0.0 - s, 0.0 - c  # negation without producing -0.0
    return ((s, c), (c, ns), (ns, nc), (nc, s))[q % 4]


def sin_cos_deg_array(angle_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elementwise :func:`sin_cos_deg` (NaN for non-finite angles)."""
    a = np.asarray(angle_deg, dtype=float)
    finite = np.isfinite(a)
    a = np.where(finite, a, 0.0)
    q = np.rint(a / 90.0)
    s, c = _sin_cos_reduced((a - 90.0 * q) * RAD_PER_DEG)
    ns, nc = 0.0 - s, 0.0 - c
    k = np.remainder(q, 4.0)
    sin = np.where(k == 0.0, s, np.where(k == 1.0, c, np.where(k == 2.0, ns, nc)))
    cos = np.where(k == 0.0, c, np.where(k == 1.0, ns, np.where(k == 2.0, nc, s)))
    return np.where(finite, sin, np.nan), np.where(finite, cos, np.nan)


def _atan_reduced_deg(u):
    """atan(u) in degrees for |u| <= tan(pi/8), by one half-angle step and a Taylor series."""
    w = u / (1.0 + np.sqrt(1.0 + u * u)) if isinstance(u, np.ndarray) else u / (1.0 + math.sqrt(1.0 + u * u))
    z = w * w
    return (2.0 * (w + w * z * _horner(z, _ATAN))) * DEG_PER_RAD


def atan2_deg(y: float, x: float) -> float:
    """Angle of the vector (x, y) in degrees, in [-180, 180]; 0 for the zero vector, NaN when either is NaN."""
    if math.isnan(x) or math.isnan(y):
        return math.nan
    ax, ay = abs(x), abs(y)
    if ax == 0.0 and ay == 0.0:
        return 0.0
    t = ay / ax if ax >= ay else ax / ay  # in [0, 1]
    a = 45.0 + _atan_reduced_deg((t - 1.0) / (t + 1.0)) if t > _TAN_PI_8 else _atan_reduced_deg(t)
    if ay > ax:
        a = 90.0 - a
    if x < 0.0:
        a = 180.0 - a
    return -a if y < 0.0 else a


def atan2_deg_array(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Elementwise :func:`atan2_deg`."""
    y, x = np.broadcast_arrays(np.asarray(y, dtype=float), np.asarray(x, dtype=float))
    ax, ay = np.abs(x), np.abs(y)
    zero = (ax == 0.0) & (ay == 0.0)
    big = np.where(ax >= ay, ax, ay)
    t = np.where(ax >= ay, ay, ax) / np.where(zero, 1.0, big)
    high = t > _TAN_PI_8
    with np.errstate(invalid="ignore"):
        a = np.where(high, 45.0 + _atan_reduced_deg((t - 1.0) / (t + 1.0)), _atan_reduced_deg(t))
    a = np.where(ay > ax, 90.0 - a, a)
    a = np.where(x < 0.0, 180.0 - a, a)
    a = np.where(y < 0.0, -a, a)
    return np.where(zero, 0.0, a)


def bearing_deg(x: float, y: float, tx: float, ty: float) -> float:
    """Absolute bearing in degrees [0, 360) from (x, y) to (tx, ty); 0 when the points coincide."""
    return atan2_deg(ty - y, tx - x) % 360.0


def hypot(x: float, y: float) -> float:
    """Euclidean length of (x, y): sqrt(x² + y²) (no overflow guard: lengths here are in cm)."""
    return math.sqrt(x * x + y * y)


def dist(p: Sequence[float], q: Sequence[float]) -> float:
    """Distance between two 2-D points."""
    dx, dy = float(q[0]) - float(p[0]), float(q[1]) - float(p[1])
    return math.sqrt(dx * dx + dy * dy)


def dot2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of arrays whose last axis has length 2."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def norm2(v: np.ndarray) -> np.ndarray:
    """Euclidean length along a last axis of length 2 (replaces ``np.linalg.norm(v, axis=-1)``)."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1])


def fsum_dot(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two 1-D arrays, correctly rounded (``math.fsum``): independent of summation order,
    unlike ``a @ b`` (BLAS)."""
    return math.fsum((a * b).tolist())


def sequential_sum(a: np.ndarray) -> np.ndarray:
    """Sums along the last axis, added strictly left to right (``np.add.accumulate``: each partial sum needs
    the previous one, so no SIMD width or BLAS kernel can change the order). Faster than :func:`math.fsum`
    on long rows; error at most about n·2⁻⁵³ relative for non-negative terms."""
    return np.add.accumulate(a, axis=-1)[..., -1]


def fsum_mean(a: np.ndarray) -> float:
    """Mean of a non-empty 1-D array, from its correctly rounded sum."""
    return math.fsum(a.tolist()) / len(a)


def exp_array(x: np.ndarray) -> np.ndarray:
    """Elementwise e**x (0 below -745.2, inf above 709.8, NaN for NaN)."""
    x = np.asarray(x, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        k = np.clip(np.rint(np.where(np.isnan(x), 0.0, x) * _INV_LN2), -1100.0, 1100.0)
        r = (x - k * _LN2_HI) - k * _LN2_LO  # |r| <= ln2 / 2 inside the finite range
        out = np.ldexp(_horner(r, _EXP), k.astype(np.int32))
    out = np.where(x < -746.0, 0.0, np.where(x > 710.0, np.inf, out))
    return np.where(np.isnan(x), np.nan, out)


def log_array(x: np.ndarray) -> np.ndarray:
    """Elementwise natural logarithm of positive finite values (-inf at 0; NaN below 0)."""
    x = np.asarray(x, dtype=float)
    m, e = np.frexp(x)  # x = m * 2**e, m in [0.5, 1)
    small = m < _SQRT_HALF
    m = np.where(small, m * 2.0, m)  # m in [sqrt(1/2), sqrt(2))
    e = np.where(small, e - 1, e).astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):  # x <= 0 is answered below
        s = (m - 1.0) / (m + 1.0)  # log m = 2 atanh(s), |s| <= 0.1716
        z = s * s
        two_s = 2.0 * s
        out = e * _LN2_HI + ((two_s + two_s * z * _horner(z, _ATANH)) + e * _LN2_LO)
    return np.where(x > 0.0, out, np.where(x == 0.0, -np.inf, np.nan))
