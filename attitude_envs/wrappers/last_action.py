"""The observation with the previous command: memory of what the agent itself sent.

Under a computation delay (flight conditions' one control period) the command that acts
during a step is the one decided a period earlier. The plant's state alone is then not
Markov; the state with the commands in flight is (Katsikopoulos & Engelbrecht 2003, "Markov
decision processes with delays and asynchronous cost collection", IEEE TAC 48(4): the
delay-augmented state). A flight computer knows the command it sent, so appending it to the
observation gives a memoryless policy that state. For a linear actor ``u_k = K [y_k; u_{k-1}]``
is the class of the LQR designed for a one-period delay (``baselines.lqr`` with
``delay_steps``). RL Baselines3 Zoo's ``HistoryWrapper`` appends past actions the same way.

:class:`LastAction` is the training-side wrapper (the Zoo's ``env_wrapper`` key); its
:meth:`LastAction.wrap_policy` is the playing-side twin that a saved model trained behind it
plays behind (:func:`experiments.policies.build_policy`), and
:class:`attitude_envs.jax.wrappers.LastAction` the JAX plants' twin for the fused trainer.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np


def _box_pair(obs: gym.Space, act: gym.Space) -> tuple[gym.spaces.Box, gym.spaces.Box]:
    if not (isinstance(obs, gym.spaces.Box) and len(obs.shape) == 1 and isinstance(act, gym.spaces.Box)):
        raise ValueError(f"LastAction needs a flat Box observation and a Box action space, got {obs} and {act}")
    return obs, act


def observation_space_with_action(observation_space: gym.Space, action_space: gym.Space) -> gym.spaces.Box:
    """The observation box followed by the action box (float32)."""
    obs, act = _box_pair(observation_space, action_space)
    low = np.concatenate([obs.low, np.asarray(act.low, dtype=np.float32).reshape(-1)])
    high = np.concatenate([obs.high, np.asarray(act.high, dtype=np.float32).reshape(-1)])
    return gym.spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


class _ActionMemory:
    """The previous action, clipped to ``env``'s action box (zeros after :meth:`reset`), and the
    observation followed by it: the one memory :class:`LastAction` and its policy-side twin
    share, so that a model sees the same numbers in training and in play."""

    def __init__(self, env: gym.Env) -> None:
        _, act = _box_pair(env.observation_space, env.action_space)
        self._low, self._high = act.low, act.high
        self.last = np.zeros(act.shape, dtype=np.float32)

    def reset(self) -> None:
        self.last = np.zeros_like(self.last)

    def record(self, action: Any) -> None:
        self.last = np.clip(np.asarray(action, dtype=np.float32), self._low, self._high)

    def seen(self, obs: np.ndarray) -> np.ndarray:
        return np.concatenate([np.asarray(obs, dtype=np.float32), self.last.reshape(-1)])


class LastAction(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The observation followed by the previous action, clipped to the action box (zeros after
    ``reset``); everything else is the env's. See the module docstring."""

    #: the JAX plants' twin, which the fused trainer applies in its place
    jax_twin = "attitude_envs.jax.wrappers.LastAction"

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        self._memory = _ActionMemory(env)
        self.observation_space = observation_space_with_action(env.observation_space, env.action_space)

    @property
    def last_action(self) -> np.ndarray:
        """The previous action as observed (clipped; zeros after ``reset``), a copy."""
        return self._memory.last.copy()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._memory.reset()
        return self._memory.seen(obs), info

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._memory.record(action)
        return self._memory.seen(obs), reward, terminated, truncated, info

    @staticmethod
    def wrap_policy(policy, env: gym.Env) -> WithLastAction:
        """The playing-side twin of this wrapper: ``policy`` sees the observation followed by its
        own previous action."""
        return WithLastAction(policy, env)

    @staticmethod
    def observation_space_of(observation_space: gym.Space, action_space: gym.Space) -> gym.spaces.Box:
        """The observation space of a model trained behind this wrapper on an env with these spaces."""
        return observation_space_with_action(observation_space, action_space)


class WithLastAction:
    """``policy`` (``reset(seed)``, ``act(obs, info)``) fed the observation followed by the
    action it returned at the previous step, clipped to ``env``'s action box (zeros after
    ``reset``), as :class:`LastAction` feeds it in training."""

    def __init__(self, policy, env: gym.Env) -> None:
        self.policy = policy
        self.name = getattr(policy, "name", type(policy).__name__)
        self._memory = _ActionMemory(env)

    def reset(self, seed: int | None = None) -> None:
        self.policy.reset(seed)
        self._memory.reset()

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        action = self.policy.act(self._memory.seen(obs), info)
        self._memory.record(action)
        return action
