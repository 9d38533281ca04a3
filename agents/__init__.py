"""Learning agents (the Q-learning LQR, Stable-Baselines3 glue)."""

from agents.qlqr import QLearningLQR

__all__ = ["QLearningLQR"]
