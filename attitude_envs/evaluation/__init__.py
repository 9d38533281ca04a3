"""The policy-agnostic evaluation core: the Policy interface, rollouts, traces, metrics, each env's
success metric, the evaluator grid.

Campaigns, reports and plots live one layer up, in ``experiments``."""

from attitude_envs.evaluation.metrics import episode_metrics
from attitude_envs.evaluation.policy import Policy
from attitude_envs.evaluation.rollout import rollout
from attitude_envs.evaluation.runner import Evaluation, Scenario, evaluate, write_csv, write_json
from attitude_envs.evaluation.success import FINAL_ERROR_DEG, FINAL_STATE_FRACTION, SuccessMetric
from attitude_envs.evaluation.trace import EpisodeTrace, StateTrace, record_episode, record_state_trace

__all__ = [
    "FINAL_ERROR_DEG",
    "FINAL_STATE_FRACTION",
    "EpisodeTrace",
    "Evaluation",
    "Policy",
    "Scenario",
    "StateTrace",
    "SuccessMetric",
    "episode_metrics",
    "evaluate",
    "record_episode",
    "record_state_trace",
    "rollout",
    "write_csv",
    "write_json",
]
