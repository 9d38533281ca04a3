"""Gymnasium environments."""

from attitude_envs.envs.linear_system import LinearSystemEnv
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv

__all__ = ["LinearSystemEnv", "ReactionWheelEnv"]
