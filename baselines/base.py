"""The one policy interface every controller, learned or analytic, is evaluated through."""

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


class ZeroPolicy:
    """Commands nothing: the passive (free-drift) reference."""

    name = "zero"

    def __init__(self, env) -> None:
        self._shape = env.action_space.shape

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return np.zeros(self._shape, dtype=np.float32)
