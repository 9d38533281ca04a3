"""Statistics of a leaderboard cell: the percentile bootstrap CI of the mean, the IQM, whether
every episode gave the same value, and J / J* as a ratio of means with a paired bootstrap CI."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats


def bootstrap_ci(
    values: Sequence[float], n_boot: int = 2000, level: float = 0.95, seed: int = 0
) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of the mean (``(nan, nan)`` for no finite value)."""
    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if len(x) == 0:
        return (float("nan"), float("nan"))
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, len(x), size=(int(n_boot), len(x)))].mean(axis=1)
    alpha = (1.0 - level) / 2.0
    return (float(np.quantile(means, alpha)), float(np.quantile(means, 1.0 - alpha)))


def iqm(values: Sequence[float]) -> float:
    """Interquartile mean (mean of the middle 50 % of the finite values)."""
    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    return float(stats.trim_mean(x, 0.25)) if len(x) else float("nan")


def finite_mean(values: Sequence[Any]) -> float:
    """Mean of the finite values (None and NaN skipped); NaN when there is none."""
    x = np.asarray([float(v) for v in values if v is not None and np.isfinite(float(v))], dtype=float)
    return float(x.mean()) if len(x) else float("nan")


def is_deterministic(values: Sequence[float]) -> bool:
    """More than one value and all equal: every seed gave the same J (e.g. a fixed start)."""
    x = np.asarray(values, dtype=float)
    return len(x) > 1 and bool(np.all(x == x[0]))


def as_flag(value: Any) -> bool:
    """A row's boolean (CSV rows carry ``"True"``/``"False"`` or 1/0)."""
    return value in (True, 1, "True", "true", "1")


def known_flag(value: Any) -> bool | None:
    """A row's boolean, None when unknown (None, ``""`` or NaN, as a CSV row carries it)."""
    if value is None or value == "" or (isinstance(value, float) and np.isnan(value)):
        return None
    return as_flag(value)


def ratio_stats(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """J / J* of a cell as a ratio of means: Σ J / Σ J* over the episodes that have a J*, with a
    95 % paired bootstrap CI (episodes resampled with their J and J* together), the median of
    the per-episode ratios, whether every episode gave the same ratio, and how many episodes had
    a J*. A mean of per-episode ratios would be dominated by episodes that start near the
    target, where J* is close to zero and any controller's ratio is huge."""
    pairs = [
        (float(r["J"]), float(r["j_star"]))
        for r in rows
        if r.get("j_star") is not None
        and np.isfinite(float(r["j_star"]))
        and float(r["j_star"]) > 0.0
        and np.isfinite(float(r["J"]))
    ]
    if not pairs:
        return {
            "J_over_J_star": float("nan"),
            "J_over_J_star_ci_low": float("nan"),
            "J_over_J_star_ci_high": float("nan"),
            "J_over_J_star_median": float("nan"),
            "J_over_J_star_deterministic": False,
            "J_over_J_star_episodes": 0,
        }
    J, Js = np.asarray(pairs).T
    ratios = J / Js
    deterministic = is_deterministic(ratios)
    lo, hi = (float("nan"), float("nan"))
    if not deterministic:
        idx = np.random.default_rng(0).integers(0, len(J), size=(2000, len(J)))
        boot = J[idx].sum(axis=1) / Js[idx].sum(axis=1)
        lo, hi = float(np.quantile(boot, 0.025)), float(np.quantile(boot, 0.975))
    return {
        "J_over_J_star": float(J.sum() / Js.sum()),
        "J_over_J_star_ci_low": lo,
        "J_over_J_star_ci_high": hi,
        "J_over_J_star_median": float(np.median(ratios)),
        "J_over_J_star_deterministic": deterministic,
        "J_over_J_star_episodes": len(J),
    }
