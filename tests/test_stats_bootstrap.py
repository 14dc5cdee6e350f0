"""analysis.stats.bootstrap_mean: the cached resamples and the integer shortcut give exactly the numbers of the plain
percentile bootstrap (``default_rng(seed).integers(0, n, (n_boot, n))``, each resample's mean)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis import stats
from analysis.stats import bootstrap_mean


def _reference(values, n_boot: int = 2000, seed: int = 0, level: float = 0.95) -> tuple[float, float, float]:
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    if len(x) == 0 or (np.isposinf(x).any() and np.isneginf(x).any()):
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if len(x) < 2:
        return mean, math.nan, math.nan
    if np.all(x == x[0]):
        return mean, mean, mean
    means = x[np.random.default_rng(seed).integers(0, len(x), size=(n_boot, len(x)))].mean(axis=1)
    alpha = (1 - level) / 2
    method = "linear" if np.isfinite(means).all() else "inverted_cdf"
    return mean, float(np.quantile(means, alpha, method=method)), float(np.quantile(means, 1 - alpha, method=method))


def _same(a: tuple, b: tuple) -> bool:
    return all((math.isnan(p) and math.isnan(q)) or p == q for p, q in zip(a, b, strict=True))


def _samples() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    out = []
    for n in (0, 1, 2, 3, 17, 476, 1001):
        out += [rng.normal(size=n) * 50, rng.integers(0, 6, size=n).astype(float), (rng.random(n) < 0.3) * 1.0,
                rng.integers(-2, 3, size=n).astype(float), np.round(rng.normal(size=n) * 40) / 4,
                rng.integers(0, 10**12, size=n).astype(float)]
        if n > 3:
            with_inf = rng.integers(0, 6, size=n).astype(float)
            with_inf[1], with_inf[2] = np.inf, np.nan
            out.append(with_inf)
    return out


@pytest.mark.parametrize("n_boot,seed", [(2000, 0), (500, 3)])
def test_bootstrap_equals_the_plain_resampling(n_boot, seed):
    for x in _samples() * 2:  # twice: the cached results and resamples give the same numbers again
        assert _same(bootstrap_mean(x, n_boot, seed), _reference(x, n_boot, seed)), x


def test_resample_cache_is_bounded(monkeypatch):
    monkeypatch.setattr(stats, "_RESAMPLES_BYTES", 3 * 2000 * 100 * 8 * 2)
    stats._resamples.clear()
    for n in range(90, 110):
        x = np.arange(n, dtype=float) + 0.5
        assert _same(bootstrap_mean(x), _reference(x))
    assert 1 <= len(stats._resamples) <= 3
