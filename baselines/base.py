"""The policy interface of the controllers (``Policy``, from ``attitude_envs.evaluation``) and the zero policy.

The Stable-Baselines3 adapter ``SB3Policy`` lives in ``experiments.training.policy``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attitude_envs.evaluation.policy import Policy

__all__ = ["Policy", "ZeroPolicy"]


class ZeroPolicy:
    """Commands nothing: the passive (free-drift) reference."""

    name = "zero"

    def __init__(self, env) -> None:
        self._shape = env.action_space.shape

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return np.zeros(self._shape, dtype=np.float32)
