"""Interval estimates for the reports: Wilson score interval, percentile bootstrap, paired differences."""

from __future__ import annotations

import math

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
    return p, max(0.0, centre - half), min(1.0, centre + half)


def bootstrap_mean(values, n_boot: int = 2000, seed: int = 0, level: float = 0.95) -> tuple[float, float, float]:
    """Mean and percentile-bootstrap interval of the mean (NaNs dropped; interval NaN below 2 values; with an
    infinite value the mean is infinite and so is an end of the interval).

    Seeded, so a report is reproducible."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    if len(x) == 0:
        return math.nan, math.nan, math.nan
    if np.isposinf(x).any() and np.isneginf(x).any():  # +inf and -inf together: no mean
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if len(x) < 2:
        return mean, math.nan, math.nan
    if np.all(x == x[0]):
        return mean, mean, mean
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, len(x), size=(n_boot, len(x)))].mean(axis=1)
    alpha = (1 - level) / 2
    # an infinite value (min_ttc_s: never on a collision course) makes resampled means infinite; interpolating
    # between two of them is inf - inf (NaN, and a warning): take order statistics instead, e.g. [1.2, inf]
    method = "linear" if np.isfinite(means).all() else "inverted_cdf"
    return (mean, float(np.quantile(means, alpha, method=method)),
            float(np.quantile(means, 1 - alpha, method=method)))


def excludes_zero(lo: float, hi: float) -> bool:
    """Whether an interval lies entirely on one side of zero."""
    return not (math.isnan(lo) or math.isnan(hi)) and (lo > 0 or hi < 0)
