"""Interval estimates for the reports: Wilson score interval, percentile bootstrap (plain, and stratified for a
mean of strata's means), paired differences."""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Sequence

import numpy as np

Z95 = 1.959963984540054


def wilson(successes: int, n: int, z: float = Z95) -> tuple[float, float, float]:
    """Proportion and its Wilson score interval (95 % by default); NaNs for n = 0."""
    if n == 0:
        return math.nan, math.nan, math.nan
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # at 0 and n successes the exact bound is 0 (1): centre - half rounds to 5.6e-17 (1 - 1.1e-16)
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return p, low, high


_RESAMPLES_BYTES = 256 * 2**20
"""Memory the cached resampling indices may hold (a report of 10,000 episodes needs a few dozen sizes)."""
_resamples: OrderedDict[tuple[int, int, int], list] = OrderedDict()
_RESULTS_MAX = 20_000
_results: OrderedDict[tuple, tuple[float, float, float]] = OrderedDict()
_EXACT_SUM = 2.0**52
"""Sums of integers below this are exact in float64 whatever the order of the additions."""


def _resample(n: int, n_boot: int, seed: int) -> list:
    """[indices (n_boot, n), their counts per row or None]: the resampling of ``n`` values that the seeded generator
    draws (the same for every sample of ``n`` values, so it is drawn once and kept: drawing it was most of a report's
    time); least recently used sizes are dropped beyond :data:`_RESAMPLES_BYTES`."""
    key = (n, n_boot, seed)
    entry = _resamples.get(key)
    if entry is not None:
        _resamples.move_to_end(key)
        return entry
    entry = [np.random.default_rng(seed).integers(0, n, size=(n_boot, n)), None]
    _resamples[key] = entry
    while len(_resamples) > 1 and sum(e[0].nbytes * 2 for e in _resamples.values()) > _RESAMPLES_BYTES:
        _resamples.popitem(last=False)
    return entry


def _resampled_means(x: np.ndarray, n_boot: int, seed: int) -> np.ndarray:
    """The means of the ``n_boot`` seeded resamples of ``x``: ``x[indices].mean(axis=1)``. For integers (counts,
    booleans, steps) whose sums are exact in float64 whatever the order, the same numbers from the resamples' counts
    of each value (a matrix product instead of gathering ``n_boot`` x ``n`` values)."""
    entry = _resample(len(x), n_boot, seed)
    indices = entry[0]
    if np.isfinite(x).all() and np.abs(x).sum() * len(x) < _EXACT_SUM and (x == np.round(x)).all():
        if entry[1] is None:
            n = len(x)
            flat = (indices + (np.arange(n_boot) * n)[:, None]).ravel()
            entry[1] = np.bincount(flat, minlength=n_boot * n).reshape(n_boot, n).astype(float)
        return entry[1] @ x / len(x)
    return x[indices].mean(axis=1)


def bootstrap_mean(values, n_boot: int = 2000, seed: int = 0, level: float = 0.95) -> tuple[float, float, float]:
    """Mean and percentile-bootstrap interval of the mean (NaNs dropped; interval NaN below 2 values; with an
    infinite value the mean is infinite and so is an end of the interval).

    Seeded, so a report is reproducible: the resamples are those of ``default_rng(seed).integers(0, n, (n_boot,
    n))`` for ``n`` values. The result of equal values is kept, so that figures and tables showing the same
    interval compute it once."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    key = (hashlib.blake2b(x.tobytes(), digest_size=20).digest(), len(x), n_boot, seed, level)  # small keys
    if key in _results:
        _results.move_to_end(key)
        return _results[key]
    result = _bootstrap_mean(x, n_boot, seed, level)
    _results[key] = result
    if len(_results) > _RESULTS_MAX:
        _results.popitem(last=False)
    return result


def _bootstrap_mean(x: np.ndarray, n_boot: int, seed: int, level: float) -> tuple[float, float, float]:
    if len(x) == 0:
        return math.nan, math.nan, math.nan
    if np.isposinf(x).any() and np.isneginf(x).any():  # +inf and -inf together: no mean
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if len(x) < 2:
        return mean, math.nan, math.nan
    if np.all(x == x[0]):
        return mean, mean, mean
    means = _resampled_means(x, n_boot, seed)
    alpha = (1 - level) / 2
    # an infinite value (min_ttc_s: never on a collision course) makes resampled means infinite; interpolating
    # between two of them is inf - inf (NaN, and a warning): take order statistics instead, e.g. [1.2, inf]
    method = "linear" if np.isfinite(means).all() else "inverted_cdf"
    low, high = np.quantile(means, [alpha, 1 - alpha], method=method)
    return mean, float(low), float(high)


def stratum_seed(seed: int, stratum: int) -> int:
    """The seed of stratum ``stratum``'s resampling in :func:`stratified_bootstrap_mean`: ``seed`` itself for the
    first (one stratum is the plain bootstrap of :func:`bootstrap_mean`), an independent stream for the others
    (the same indices for two strata of one size would resample them together, not independently)."""
    if stratum == 0:
        return seed
    return int(np.random.SeedSequence([seed, stratum]).generate_state(1, dtype=np.uint64)[0])


def stratified_bootstrap_mean(strata: Sequence, n_boot: int = 2000, seed: int = 0, level: float = 0.95
                              ) -> tuple[float, float, float]:
    """Mean over strata of each stratum's mean, and its percentile-bootstrap interval from resampling the values
    within each stratum (each stratum keeps its size and its weight: one stratum per scenario, its held-out seeds
    as values, so that every scenario weighs the same however many of its episodes count).

    NaNs are dropped per stratum. NaN mean when there is no stratum or a stratum has no value; NaN interval when a
    stratum has fewer than 2 values (as :func:`bootstrap_mean`). Seeded (stratum ``k`` resamples with
    :func:`stratum_seed`), so a report is reproducible; one stratum gives :func:`bootstrap_mean`'s numbers."""
    xs = [np.asarray(values, dtype=float) for values in strata]
    xs = [x[~np.isnan(x)] for x in xs]
    if not xs or any(len(x) == 0 for x in xs):
        return math.nan, math.nan, math.nan
    if len(xs) == 1:
        return bootstrap_mean(xs[0], n_boot, seed, level)
    if any(np.isposinf(x).any() for x in xs) and any(np.isneginf(x).any() for x in xs):
        return math.nan, math.nan, math.nan
    mean = math.fsum(float(x.mean()) for x in xs) / len(xs)
    if any(len(x) < 2 for x in xs):
        return mean, math.nan, math.nan
    if all(np.all(x == x[0]) for x in xs):
        return mean, mean, mean
    means = np.zeros(n_boot)
    for k, x in enumerate(xs):  # a constant stratum resamples to its own mean
        means += x[0] if np.all(x == x[0]) else _resampled_means(x, n_boot, stratum_seed(seed, k))
    means /= len(xs)
    alpha = (1 - level) / 2
    method = "linear" if np.isfinite(means).all() else "inverted_cdf"  # as in _bootstrap_mean: no inf - inf
    low, high = np.quantile(means, [alpha, 1 - alpha], method=method)
    return mean, float(low), float(high)


def excludes_zero(lo: float, hi: float) -> bool:
    """Whether an interval lies entirely on one side of zero."""
    return not (math.isnan(lo) or math.isnan(hi)) and (lo > 0 or hi < 0)
