"""The one policy interface every controller, learned or analytic, is evaluated through.

Rollouts (:func:`attitude_envs.evaluation.rollout.rollout`, :func:`~attitude_envs.evaluation.trace.record_episode`)
take any object with this shape; ``baselines.base`` re-exports it for the controllers.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Policy(Protocol):
    """``reset(seed)`` at the start of an episode, then ``act(obs, info)`` every step,
    returning the env's (normalized) action."""

    name: str

    def reset(self, seed: int | None = None) -> None: ...

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray: ...
