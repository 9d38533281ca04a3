"""Statistics of a leaderboard cell: the percentile bootstrap CI of the mean, the IQM, whether
every episode gave the same value, J / J* as a ratio of means with a paired bootstrap CI and the
CVaR of the per-episode ratios, and the constraint outcome of a cell with constraints.

The bootstraps are :func:`scipy.stats.bootstrap`'s (percentile method, :data:`N_BOOT`
resamples, a generator seeded with :data:`SEED`: the same rows give the same interval on every
run); the IQM is :func:`scipy.stats.trim_mean` with a quarter cut at each end."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats

#: bootstrap resamples of every interval of a report
N_BOOT = 2000

#: the seed of the generator every bootstrap of a report draws from
SEED = 0


def bootstrap_ci(
    values: Sequence[float], n_boot: int = N_BOOT, level: float = 0.95, seed: int = SEED
) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of the mean of the finite ``values`` (their unit),
    by :func:`scipy.stats.bootstrap` (``method="percentile"``, ``n_boot`` resamples, a generator
    seeded with ``seed``): ``(nan, nan)`` for no finite value, ``(v, v)`` for a single one (every
    resample is that value)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if len(x) == 0:
        return (float("nan"), float("nan"))
    if len(x) == 1:
        return (float(x[0]), float(x[0]))
    res = stats.bootstrap(
        (x,),
        np.mean,
        n_resamples=int(n_boot),
        confidence_level=level,
        method="percentile",
        vectorized=True,
        random_state=np.random.default_rng(seed),
    )
    return (float(res.confidence_interval.low), float(res.confidence_interval.high))


def _ratio_of_sums(j: np.ndarray, j_star: np.ndarray, axis: int = -1) -> np.ndarray:
    """Σ J / Σ J* along ``axis`` (the statistic of :func:`ratio_stats`'s paired bootstrap)."""
    return j.sum(axis=axis) / j_star.sum(axis=axis)


def iqm(values: Sequence[float]) -> float:
    """Interquartile mean (mean of the middle 50 % of the finite values)."""
    x = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    return float(stats.trim_mean(x, 0.25)) if len(x) else float("nan")


def cvar(values: Sequence[float], alpha: float = 0.1) -> float:
    """Conditional value at risk of a cost: the mean of the worst (largest) ``alpha`` share of
    the ``values``, ``⌈alpha · n⌉`` of them (Rockafellar & Uryasev's CVaR at level ``1 − alpha``;
    safe-control-gym reports it beside the mean). NaN values are left out; an infinite cost (an
    unbounded episode) stays, so the CVaR is infinite when it is among the worst; NaN for no value."""
    if not 0.0 < alpha <= 1.0:
        raise ValueError(f"alpha must be in (0, 1], got {alpha!r}")
    x = np.sort(np.asarray([v for v in values if not np.isnan(v)], dtype=float))
    if len(x) == 0:
        return float("nan")
    return float(x[-int(np.ceil(alpha * len(x))) :].mean())


def constraint_stats(rows: Sequence[Mapping[str, Any]], prefix: str = "") -> dict[str, float]:
    """The constraint outcome of a cell where its rows carry ``<prefix>violations``
    (:func:`attitude_envs.constraints.episode_summary`; ``{}`` otherwise): ``violating_rate``
    (the share of episodes with any violating step: the failure rate), ``violation_steps`` (the
    mean violating steps per episode) and ``min_margin_deg`` (the least keep-out cone margin over
    every episode, deg); each NaN unless known for every episode. ``prefix`` ``"j_star_"`` reads
    J*'s own replays."""
    if not any(f"{prefix}violations" in r for r in rows):
        return {}
    v = np.asarray([_number(r.get(f"{prefix}violations")) for r in rows])
    m = np.asarray([_number(r.get(f"{prefix}min_margin_deg")) for r in rows])
    known = bool(np.all(np.isfinite(v)))
    return {
        "violating_rate": float(np.mean(v > 0)) if known else float("nan"),
        "violation_steps": float(np.mean(v)) if known else float("nan"),
        "min_margin_deg": float(np.min(m)) if len(m) and np.all(np.isfinite(m)) else float("nan"),
    }


def _number(value: Any) -> float:
    """A row's number (CSV rows carry strings; None and ``""`` are NaN)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


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


def _has_j_star(row: Mapping[str, Any]) -> bool:
    """Whether an episode row has a finite, positive J*."""
    j_star = row.get("j_star")
    return j_star is not None and np.isfinite(float(j_star)) and float(j_star) > 0.0


def ratio_stats(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """J / J* of a cell as a ratio of means: Σ J / Σ J* over the episodes that have a J*, with a
    95 % paired percentile bootstrap CI (:func:`scipy.stats.bootstrap`, ``paired=True``: episodes
    resampled with their J and J* together), the median of
    the per-episode ratios and their CVaR₀.₁ (:func:`cvar`: the mean of the worst tenth),
    whether every episode gave the same ratio, and how many episodes had a J*. A mean of per-episode ratios would be dominated by episodes that start near the
    target, where J* is close to zero and any controller's ratio is huge."""
    pairs = [(float(r["J"]), float(r["j_star"])) for r in rows if _has_j_star(r) and np.isfinite(float(r["J"]))]
    if not pairs:
        return {
            "J_over_J_star": float("nan"),
            "J_over_J_star_cvar10": float("nan"),
            "J_over_J_star_ci_low": float("nan"),
            "J_over_J_star_ci_high": float("nan"),
            "J_over_J_star_median": float("nan"),
            "J_over_J_star_deterministic": False,
            "J_over_J_star_episodes": 0,
        }
    J, Js = np.asarray(pairs).T
    ratios = J / Js
    # the CVaR keeps the episodes whose J is not finite (an unbounded cost is the worst tail)
    tail = [
        float(r["J"]) / float(r["j_star"]) if np.isfinite(float(r["J"])) else math.inf for r in rows if _has_j_star(r)
    ]
    deterministic = is_deterministic(ratios)
    lo, hi = (float("nan"), float("nan"))
    if len(J) == 1:  # every resample is the one episode
        lo = hi = float(ratios[0])
    elif not deterministic:
        res = stats.bootstrap(
            (J, Js),
            _ratio_of_sums,
            n_resamples=N_BOOT,
            confidence_level=0.95,
            method="percentile",
            paired=True,
            vectorized=True,
            random_state=np.random.default_rng(SEED),
        )
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return {
        "J_over_J_star": float(J.sum() / Js.sum()),
        "J_over_J_star_ci_low": lo,
        "J_over_J_star_ci_high": hi,
        "J_over_J_star_median": float(np.median(ratios)),
        "J_over_J_star_cvar10": cvar(tail, 0.1),
        "J_over_J_star_deterministic": deterministic,
        "J_over_J_star_episodes": len(J),
    }
