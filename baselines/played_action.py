"""Training-side wrappers that change each action as a policy-side twin plays it."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from attitude_envs.info import policy_view


class PlayedActionWrapper(gym.Wrapper):
    """A wrapper that changes each action as its policy-side twin would: :meth:`transform` gets
    the action with the observation and :func:`~attitude_envs.info.policy_view` of the info that
    preceded it (what the policy saw), so a model trained behind the wrapper plays exactly the
    same behind the twin (``wrap_policy``). The residuals (:class:`baselines.cbf.EigenaxisResidual`,
    :class:`baselines.residual.LQRResidual`, :class:`baselines.residual.SloshLQRResidual`) and the CBF
    shield are such wrappers."""

    _last: tuple[np.ndarray, dict[str, Any]] | None = None

    @property
    def last_observation(self) -> np.ndarray | None:
        """The observation the next action answers (None before the first reset)."""
        return None if self._last is None else self._last[0]

    def transform(self, action: Any, obs: np.ndarray, info: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        """The action the env receives, and entries for the step's info."""
        raise NotImplementedError

    def on_reset(self) -> None:
        """Called at every reset."""

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self.on_reset()
        self._last = (obs, policy_view(info))
        return obs, info

    def step(self, action: Any):
        if self._last is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step()")
        applied, extra = self.transform(action, *self._last)
        obs, reward, terminated, truncated, info = self.env.step(applied)
        info.update(extra)
        self._last = (obs, policy_view(info))
        return obs, reward, terminated, truncated, info
