"""Learning agents (the Q-learning LQR, Stable-Baselines3 glue)."""

from agents.q_learning_lqr import QLearningLQR

__all__ = ["QLearningLQR"]
