"""Rollouts, metrics and reports."""

from attitude_envs.evaluation.rollout import rollout

__all__ = ["rollout"]
