"""The report's statistics: scipy's percentile bootstrap (plain and paired), the IQM, reproducible."""

import numpy as np
import pytest
from scipy import stats

from experiments.report.statistics import N_BOOT, SEED, bootstrap_ci, iqm, ratio_stats


def _costs(n: int = 25, seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).lognormal(mean=5.0, sigma=0.6, size=n)


def test_bootstrap_ci_is_scipys_percentile_interval_and_contains_the_mean():
    x = _costs()
    lo, hi = bootstrap_ci(list(x))
    assert lo < x.mean() < hi
    ref = stats.bootstrap(
        (x,), np.mean, n_resamples=N_BOOT, method="percentile", random_state=np.random.default_rng(SEED)
    ).confidence_interval
    assert (lo, hi) == pytest.approx((ref.low, ref.high), rel=1e-12)
    # a wider level gives a wider interval
    lo99, hi99 = bootstrap_ci(list(x), level=0.99)
    assert lo99 <= lo and hi99 >= hi


def test_bootstrap_ci_is_deterministic_and_depends_on_its_seed():
    x = list(_costs())
    assert bootstrap_ci(x) == bootstrap_ci(x)
    assert bootstrap_ci(x, seed=1) != bootstrap_ci(x)


def test_bootstrap_ci_edge_cases():
    assert all(np.isnan(bootstrap_ci([])))
    assert all(np.isnan(bootstrap_ci([float("nan"), float("inf")])))
    assert bootstrap_ci([3.5]) == (3.5, 3.5)
    assert bootstrap_ci([2.0, 2.0, 2.0]) == (2.0, 2.0)
    assert bootstrap_ci([1.0, float("nan"), 2.0, 3.0])[0] >= 1.0  # the NaN is skipped
    with pytest.raises(ValueError, match="level"):
        bootstrap_ci([1.0, 2.0], level=1.0)


def test_iqm_is_the_quarter_trimmed_mean():
    x = _costs(40)
    assert iqm(list(x)) == pytest.approx(stats.trim_mean(x, 0.25))
    assert iqm([1.0, float("nan"), 2.0, 3.0, 4.0]) == pytest.approx(stats.trim_mean([1.0, 2.0, 3.0, 4.0], 0.25))
    assert np.isnan(iqm([]))


def test_ratio_stats_is_scipys_paired_bootstrap_of_the_ratio_of_sums():
    j_star = _costs(30)
    j = j_star * np.random.default_rng(7).uniform(1.0, 1.5, size=30)
    rows = [{"J": a, "j_star": b} for a, b in zip(j, j_star, strict=True)]
    out = ratio_stats(rows)
    assert out["J_over_J_star"] == pytest.approx(j.sum() / j_star.sum())
    assert out["J_over_J_star_ci_low"] < out["J_over_J_star"] < out["J_over_J_star_ci_high"]
    ref = stats.bootstrap(
        (j, j_star),
        lambda a, b, axis=-1: a.sum(axis=axis) / b.sum(axis=axis),
        n_resamples=N_BOOT,
        paired=True,
        vectorized=True,
        method="percentile",
        random_state=np.random.default_rng(SEED),
    ).confidence_interval
    assert (out["J_over_J_star_ci_low"], out["J_over_J_star_ci_high"]) == pytest.approx((ref.low, ref.high))
    assert ratio_stats(rows) == out  # reproducible
    assert out["J_over_J_star_episodes"] == 30 and out["J_over_J_star_median"] == pytest.approx(np.median(j / j_star))


def test_ratio_stats_without_an_interval():
    same = ratio_stats([{"J": 2.0 * s, "j_star": s} for s in (1.0, 2.0, 3.0)])  # every episode the same ratio
    assert same["J_over_J_star_deterministic"] and np.isnan(same["J_over_J_star_ci_low"])
    one = ratio_stats([{"J": 3.0, "j_star": 2.0}])
    assert one["J_over_J_star"] == one["J_over_J_star_ci_low"] == one["J_over_J_star_ci_high"] == 1.5
    none = ratio_stats([{"J": 3.0, "j_star": float("nan")}, {"J": 3.0}])
    assert none["J_over_J_star_episodes"] == 0 and np.isnan(none["J_over_J_star"])
