"""Leaderboards: one ranked list of agents per env × scenario × fault cell, J*'s own unranked
line (the oracle optimum, :func:`oracle_entry`), and which agents a report picks from a board."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from attitude_envs.evaluation.success import METRICS
from experiments.campaign.store import J_STAR_PREFIX
from experiments.report.statistics import (
    as_flag,
    bootstrap_ci,
    constraint_stats,
    finite_mean,
    iqm,
    is_deterministic,
    known_flag,
    ratio_stats,
)

#: the paper metrics a leaderboard shows (mean over the cell's episodes) where its rows carry them
PAPER_METRICS = ("eulerint_deg_s", "settling_time_abs_s", "final_error_deg", "peak_wheel_speed_rpm")

#: the name of J*'s own line on a leaderboard (not an agent: unranked, never "best")
ORACLE_AGENT = "J* (oracle)"


def leaderboards(
    rows: Sequence[Mapping[str, Any]], thresholds: Mapping[str, float] | None = None
) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """``(env, scenario, fault)`` → one entry per agent, best first: the agents whose every
    episode ran to the time limit by J mean, then those with episodes that terminated early
    (a limit crossed: the vehicle lost), by the fraction that did, then J. J sums the cost
    only up to the end of the episode, so an episode cut short costs less; ranking it by J
    alone would reward ending it (an agent trained on the reward −cost can learn exactly that).
    In a cell with constraints, agents with violating episodes rank after those without (by
    their share, then J): a cheaper slew through a keep-out cone is no better one.

    Where the rows carry J* (``j_star``), each board ends with J*'s own line
    (:func:`oracle_entry`, ``"oracle": True``, agent :data:`ORACLE_AGENT`): unranked, no
    agent. ``thresholds``: success-metric name → the campaign's threshold
    (:func:`campaign_thresholds`) that J*'s success is judged at (default: each metric's own)."""
    cells: dict[tuple[str, str, str], dict[str, list[Mapping[str, Any]]]] = {}
    for r in rows:
        cells.setdefault((r["env"], r["scenario"], r["fault"]), {}).setdefault(r["agent"], []).append(r)
    out = {}
    for cell, agents in cells.items():
        board = []
        for agent, rs in agents.items():
            J = [float(r["J"]) for r in rs]
            deterministic = is_deterministic(J)
            lo, hi = (float("nan"), float("nan")) if deterministic else bootstrap_ci(J)
            entry = {
                "agent": agent,
                "episodes": len(rs),
                "train_seeds": len({r.get("train_seed") for r in rs}),
                "J_mean": finite_mean(J),
                "J_ci_low": lo,
                "J_ci_high": hi,
                "deterministic": deterministic,
                "J_iqm": iqm(J),
                "success_rate": float(np.mean([bool(r.get("success")) for r in rs])),
                "terminated_rate": float(np.mean([as_flag(r.get("terminated")) for r in rs])),
                "recovery_time_s": finite_mean([r.get("recovery_time_s") for r in rs]),
                **ratio_stats(rs),
                **constraint_stats(rs),
            }
            for m in PAPER_METRICS:
                if any(m in r for r in rs):
                    entry[m] = finite_mean([r.get(m) for r in rs])
            board.append(entry)
        board.sort(key=_rank_key)
        oracle = oracle_entry([r for rs in agents.values() for r in rs], thresholds, board[0])
        out[cell] = board + ([oracle] if oracle is not None else [])
    return dict(sorted(out.items()))


def _rank_key(e: Mapping[str, Any]) -> tuple:
    """An entry's place: finite J first, then fewest episodes ended early, then (a cell with
    constraints) the fewest episodes with a violation, then the lowest J mean."""
    violating = e.get("violating_rate", 0.0)
    return (
        not np.isfinite(e["J_mean"]),
        e["terminated_rate"],
        violating if np.isfinite(violating) else 1.0,
        e["J_mean"],
    )


def is_oracle(entry: Mapping[str, Any]) -> bool:
    """Whether a leaderboard entry is J*'s own line (:func:`oracle_entry`), not an agent."""
    return bool(entry.get("oracle"))


def campaign_thresholds(campaign: Any) -> dict[str, float]:
    """Success-metric name → ``campaign``'s threshold (``campaign.success_threshold(metric)``)
    for every metric of :data:`~attitude_envs.evaluation.success.METRICS`."""
    return {name: float(campaign.success_threshold(metric)) for name, metric in METRICS.items()}


def oracle_success(row: Mapping[str, Any], thresholds: Mapping[str, float] | None = None) -> bool | None:
    """Whether J* itself succeeds on ``row``'s episode, by the campaign's criterion: J* finite,
    its replay not terminated and its success-metric measurements (``j_star_<name>``
    columns, :func:`experiments.campaign.store.optimum_outcome`) meeting the metric
    (:meth:`~attitude_envs.evaluation.success.SuccessMetric.met`) at ``thresholds[metric]``
    (default: the metric's own). None when J*'s measurements are unknown."""
    metric = METRICS.get(str(row.get(f"{J_STAR_PREFIX}metric") or ""))
    terminated = known_flag(row.get(f"{J_STAR_PREFIX}terminated"))
    j_star = float(row.get("j_star", float("nan")))
    if metric is None or terminated is None or not np.isfinite(j_star):
        return None
    try:
        measured = {n: float(row[f"{J_STAR_PREFIX}{n}"]) for n in metric.measurement_names()}
    except (KeyError, TypeError, ValueError):
        return None
    threshold = (thresholds or {}).get(metric.name, metric.threshold)
    return bool(not terminated and metric.met(measured, threshold))


def oracle_entry(
    rows: Sequence[Mapping[str, Any]],
    thresholds: Mapping[str, float] | None = None,
    like: Mapping[str, Any] | None = None,
) -> dict[str, Any] | None:
    """J*'s own line for one cell's ``rows`` (every agent's; one J* per episode, so episodes
    are the distinct seeds), None when the rows carry no ``j_star``: ``J_mean`` the mean J*
    (over the episodes that have one), its CI and IQM, ``J_over_J_star`` 1 by construction,
    ``success_rate`` J*'s own (:func:`oracle_success`) and ``terminated_rate`` its replay's —
    each NaN unless known for every episode (``success_known``, ``terminated_known``: how
    many are). The paper metrics of ``like`` (an agent's entry) are NaN but
    ``final_error_deg`` (deg), which J*'s measurements give where known for every episode."""
    if not any("j_star" in r for r in rows):
        return None
    episodes = list({r["seed"]: r for r in rows}.values())
    n = len(episodes)
    js = [float(r.get("j_star", float("nan"))) for r in episodes]
    finite = [j for j in js if np.isfinite(j)]
    deterministic = is_deterministic(finite)
    lo, hi = (float("nan"), float("nan")) if deterministic else bootstrap_ci(finite)
    success = [oracle_success(r, thresholds) for r in episodes]
    ended = [known_flag(r.get(f"{J_STAR_PREFIX}terminated")) for r in episodes]
    known_success = [s for s in success if s is not None]
    known_ended = [t for t in ended if t is not None]
    entry: dict[str, Any] = {
        "agent": ORACLE_AGENT,
        "oracle": True,
        "episodes": n,
        "train_seeds": 0,
        "J_mean": finite_mean(finite),
        "J_ci_low": lo,
        "J_ci_high": hi,
        "deterministic": deterministic,
        "J_iqm": iqm(finite),
        "success_rate": float(np.mean(known_success)) if len(known_success) == n else float("nan"),
        "success_known": len(known_success),
        "terminated_rate": float(np.mean(known_ended)) if len(known_ended) == n else float("nan"),
        "terminated_known": len(known_ended),
        "recovery_time_s": float("nan"),
        "J_over_J_star": 1.0 if finite else float("nan"),
        "J_over_J_star_ci_low": float("nan"),
        "J_over_J_star_ci_high": float("nan"),
        "J_over_J_star_median": 1.0 if finite else float("nan"),
        "J_over_J_star_cvar10": 1.0 if finite else float("nan"),
        "J_over_J_star_deterministic": bool(finite),
        "J_over_J_star_episodes": len(finite),
    }
    if like is not None and "violating_rate" in like:  # J*'s own replays (its measurements)
        entry |= constraint_stats(episodes, J_STAR_PREFIX)
    for m in PAPER_METRICS:
        if like is not None and m in like:
            entry[m] = float("nan")
    if "final_error_deg" in entry:
        errors = [r.get(f"{J_STAR_PREFIX}final_error_deg") for r in episodes]
        if all(e not in (None, "") and np.isfinite(float(e)) for e in errors):
            entry["final_error_deg"] = finite_mean(errors)
    return entry


def best_entry(
    board: Sequence[Mapping[str, Any]], learned: bool, trained: set[str], drift: set[str] = frozenset({"zero"})
) -> Mapping[str, Any] | None:
    """The lowest-J entry among the learned (``trained``) or the other agents; free drift
    (``drift``: the agents with ``policy: zero``) is no controller."""
    pick = [e for e in board if (e["agent"] in trained) == learned and e["agent"] not in drift and not is_oracle(e)]
    return pick[0] if pick else None


def learned_agents(campaign) -> set[str]:
    """Names of the agents that learn (SB3 models, trained or given, and the Q-learning LQR)."""
    return {a.name for a in campaign.agents if a.spec.get("policy") in ("sb3", "q-learning-lqr")}


def free_drift_agents(campaign) -> set[str]:
    """Names of the agents that apply no control (``policy: zero``)."""
    return {a.name for a in campaign.agents if a.spec.get("policy") == "zero"}


def history_agents(
    board: Sequence[Mapping[str, Any]], learned: set[str], drift: set[str] = frozenset({"zero"})
) -> list[str]:
    """The agents whose time histories a report shows for a cell: the best analytic controller
    and the best learned agent (free drift, ``drift``, is no controller); the best two when
    only one kind ran."""
    analytic, trained = best_entry(board, False, learned, drift), best_entry(board, True, learned, drift)
    picked = [e["agent"] for e in (analytic, trained) if e is not None]
    if len(picked) < 2:
        picked = [e["agent"] for e in board if e["agent"] not in drift and not is_oracle(e)][:2]
    return picked
