"""analysis.stats.bootstrap_mean: the cached resamples and the integer shortcut give exactly the numbers of the plain
percentile bootstrap (``default_rng(seed).integers(0, n, (n_boot, n))``, each resample's mean)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


def _stratified_reference(strata, n_boot: int = 2000, seed: int = 0, level: float = 0.95) -> tuple:
    """The stratified bootstrap written plainly: each stratum resampled with its own seeded generator, the means of
    the strata's resampled means, their percentiles."""
    xs = [np.asarray(s, dtype=float) for s in strata]
    means = np.zeros(n_boot)
    for k, x in enumerate(xs):
        rng = np.random.default_rng(stats.stratum_seed(seed, k))
        means += x[rng.integers(0, len(x), size=(n_boot, len(x)))].mean(axis=1)
    means /= len(xs)
    alpha = (1 - level) / 2
    return (math.fsum(float(x.mean()) for x in xs) / len(xs), float(np.quantile(means, alpha)),
            float(np.quantile(means, 1 - alpha)))


def test_stratified_bootstrap_by_hand():
    # stratum A's resampled mean is 0, 0.5 or 1 (1/4, 1/2, 1/4), B's always 10: the mean of the two is 5, 5.25 or
    # 5.5, so the 2.5 % and 97.5 % percentiles are 5 and 5.5
    assert stats.stratified_bootstrap_mean([[0, 1], [10, 10]]) == (5.25, 5.0, 5.5)
    # every stratum weighs the same whatever its size: (0.5 + 1) / 2, not the pooled 42 / 44
    mean, lo, hi = stats.stratified_bootstrap_mean([[0, 0, 1, 1], [1] * 40])
    assert mean == 0.75 and lo < mean < hi and hi <= 1.0 and lo >= 0.5


def test_stratified_bootstrap_equals_the_plain_resampling():
    rng = np.random.default_rng(11)
    for sizes in ((2, 3), (5, 5, 5), (17, 4, 30, 2), (40, 40)):
        for make in (lambda n: rng.normal(size=n) * 30, lambda n: rng.integers(0, 2, size=n).astype(float)):
            strata = [make(n) for n in sizes]
            strata = [s if not np.all(s == s[0]) else np.append(s[:-1], s[0] + 1) for s in strata]
            for n_boot, seed in ((2000, 0), (300, 5)):
                got = stats.stratified_bootstrap_mean(strata, n_boot, seed)
                want = _stratified_reference(strata, n_boot, seed)
                assert got[0] == want[0] and math.isclose(got[1], want[1], rel_tol=1e-12, abs_tol=1e-12) \
                    and math.isclose(got[2], want[2], rel_tol=1e-12, abs_tol=1e-12), (sizes, got, want)
                assert got == stats.stratified_bootstrap_mean(strata, n_boot, seed)  # reproducible


def test_stratified_bootstrap_special_cases():
    x = np.random.default_rng(3).normal(size=25)
    assert _same(stats.stratified_bootstrap_mean([x]), bootstrap_mean(x))  # one stratum: the plain bootstrap
    assert stats.stratified_bootstrap_mean([[0.0] * 4, [0.0] * 7]) == (0.0, 0.0, 0.0)  # identical methods' diffs
    assert stats.stratified_bootstrap_mean([[2.0, 2.0], [4.0, 4.0, 4.0]]) == (3.0, 3.0, 3.0)
    assert all(math.isnan(v) for v in stats.stratified_bootstrap_mean([]))
    assert all(math.isnan(v) for v in stats.stratified_bootstrap_mean([[1.0, 2.0], [math.nan]]))  # a stratum empty
    mean, lo, hi = stats.stratified_bootstrap_mean([[1.0, 2.0], [3.0]])  # a stratum of one value: no interval
    assert mean == 2.25 and math.isnan(lo) and math.isnan(hi)
    mean, lo, hi = stats.stratified_bootstrap_mean([[1.0, math.nan, 3.0], [0.0, 1.0]])  # NaNs dropped per stratum
    assert mean == 1.25 and lo <= mean <= hi
    # two strata of one size do not resample together: their seeds differ
    assert len({stats.stratum_seed(0, k) for k in range(50)}) == 50


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.floats(-1e6, 1e6), min_size=2, max_size=12), min_size=1, max_size=5),
       st.integers(0, 2**32 - 1))
def test_fuzzed_stratified_interval_lies_between_the_strata_extremes(strata, seed):
    mean, lo, hi = stats.stratified_bootstrap_mean(strata, 200, seed)
    low_end = math.fsum(min(s) for s in strata) / len(strata)
    high_end = math.fsum(max(s) for s in strata) / len(strata)
    slack = 1e-9 * (1 + max(abs(v) for s in strata for v in s))
    assert low_end - slack <= lo <= hi <= high_end + slack and low_end - slack <= mean <= high_end + slack
