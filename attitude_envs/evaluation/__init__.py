"""Rollouts, metrics, the evaluator grid, reports and plots."""

from attitude_envs.evaluation.metrics import episode_metrics
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.evaluation.runner import Evaluation, Scenario, evaluate, write_csv, write_json
from attitude_envs.evaluation.trace import EpisodeTrace, record_episode

__all__ = [
    "EpisodeTrace",
    "Evaluation",
    "Scenario",
    "episode_metrics",
    "evaluate",
    "record_episode",
    "rollout",
    "write_csv",
    "write_json",
]
