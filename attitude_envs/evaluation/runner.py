"""The evaluator: any policy on any env over a grid of scenarios × seeds → a tidy table.

One row per episode: ``scenario``, ``controller``, ``seed`` and every metric of
:func:`attitude_envs.evaluation.metrics.episode_metrics`. Scenarios carry reset options
(target, initial state) and env keyword arguments (faults, inertia samples, limits), so the
grid grows by adding scenarios. Tables are written as CSV and JSON.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.evaluation.metrics import episode_metrics
from attitude_envs.evaluation.trace import EpisodeTrace, record_episode

PolicyFactory = Callable[[gym.Env], Any]


@dataclass(frozen=True)
class Scenario:
    """A named grid point: ``options`` go to ``env.reset``, ``env_kwargs`` to the env's constructor."""

    name: str
    options: dict[str, Any] = field(default_factory=dict)
    env_kwargs: dict[str, Any] = field(default_factory=dict)


@dataclass
class Evaluation:
    """The tidy table (``rows``) and, when kept, the traces keyed ``(scenario, controller, seed)``."""

    rows: list[dict[str, Any]]
    traces: dict[tuple[str, str, int | None], EpisodeTrace]

    def where(self, **match: Any) -> list[dict[str, Any]]:
        """Rows whose columns equal every ``match`` value."""
        return [r for r in self.rows if all(r.get(k) == v for k, v in match.items())]


def evaluate(
    env: str | Callable[..., gym.Env],
    policies: Mapping[str, PolicyFactory],
    scenarios: Iterable[Scenario],
    seeds: Iterable[int | None] = (0,),
    metric_kwargs: dict[str, Any] | None = None,
    keep_traces: bool = False,
) -> Evaluation:
    """Run every policy on every scenario and seed.

    ``env``: a registered env id or a factory ``make(**env_kwargs)``; ``policies``: controller
    name → factory building the policy from the env (model-based controllers read
    ``env.unwrapped.model``); ``metric_kwargs`` go to :func:`episode_metrics`.
    """
    make = (lambda **kw: gym.make(env, **kw)) if isinstance(env, str) else env
    if not callable(make):
        raise ValueError(f"env must be an env id or a callable returning an env, got {env!r}")
    if not policies:
        raise ValueError("policies must name at least one policy factory")
    scenarios = list(scenarios)
    seeds = list(seeds)
    if not scenarios or not seeds:
        raise ValueError("scenarios and seeds must each contain at least one entry")
    rows: list[dict[str, Any]] = []
    traces: dict[tuple[str, str, int | None], EpisodeTrace] = {}
    for scenario in scenarios:
        instance = make(**scenario.env_kwargs)
        try:
            for controller, factory in policies.items():
                policy = factory(instance)
                for seed in seeds:
                    trace = record_episode(instance, policy, seed=seed, options=dict(scenario.options))
                    metrics = episode_metrics(trace, **(metric_kwargs or {}))
                    rows.append({"scenario": scenario.name, "controller": controller, "seed": seed, **metrics})
                    if keep_traces:
                        traces[(scenario.name, controller, seed)] = trace
        finally:
            instance.close()
    return Evaluation(rows, traces)


def write_csv(rows: list[dict[str, Any]], path: str | Path) -> Path:
    """Write the rows as CSV (columns: the union of the rows' keys, in first-seen order)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    columns: list[str] = []
    for r in rows:
        columns.extend(k for k in r if k not in columns)
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return path


def write_json(rows: list[dict[str, Any]], path: str | Path) -> Path:
    """Write the rows as a JSON list (NaN kept as ``NaN``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean = [{k: (v.item() if isinstance(v, np.generic) else v) for k, v in r.items()} for r in rows]
    path.write_text(json.dumps(clean, indent=2) + "\n", encoding="utf-8")
    return path
