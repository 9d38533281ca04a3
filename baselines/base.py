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


class SB3Policy:
    """Adapts a Stable-Baselines3 model (anything with ``predict(obs, state, episode_start,
    deterministic)``) to the Policy interface; recurrent state is reset by ``reset``."""

    def __init__(self, model, deterministic: bool = True, name: str | None = None) -> None:
        if not callable(getattr(model, "predict", None)):
            raise ValueError(f"model must have a predict(obs, ...) method (a Stable-Baselines3 model), got {model!r}")
        self.model = model
        self.deterministic = bool(deterministic)
        self.name = name or f"sb3-{type(model).__name__.lower()}"
        self._state = None
        self._episode_start = np.ones((1,), dtype=bool)

    def reset(self, seed: int | None = None) -> None:
        self._state = None
        self._episode_start = np.ones((1,), dtype=bool)

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        action, self._state = self.model.predict(
            obs, state=self._state, episode_start=self._episode_start, deterministic=self.deterministic
        )
        self._episode_start = np.zeros((1,), dtype=bool)
        return np.asarray(action, dtype=np.float32)
