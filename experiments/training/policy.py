"""``SB3Policy``: a Stable-Baselines3 model behind the Policy interface (``reset(seed)``, ``act(obs, info)``).

Needs no SB3 import itself: anything with SB3's ``predict`` signature can be wrapped.
"""

from __future__ import annotations

from typing import Any

import numpy as np


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
