"""Shared machinery of the natively batched envs: seeding, resets and autoreset.

A batched env keeps one single-env instance per sub-env for resets (so initial-state,
inertia and fault draws are exactly the single env's) and advances all sub-envs in one
compiled call. Sub-env ``i`` reset with seed ``s`` follows the single env reset with
``s + i``, as gymnasium's and SB3's vector envs seed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from attitude_envs import validation


class BatchedEnv(VectorEnv):
    """Subclasses implement ``_load(i)`` (copy sub-env ``i``'s fresh state into the batch
    arrays), ``_advance(actions)`` (one batched step → rewards, terminated, truncated, info
    dict of arrays) and ``_observations()``.

    ``autoreset_mode``: ``"next_step"`` (gymnasium's default: the step after an episode
    ends resets that sub-env, ignores its action, reward 0) or ``"same_step"`` (the
    sub-env resets in the step that ends it; ``infos["final_obs"]`` holds its last
    observation; what SB3 expects).
    """

    def __init__(self, single_env_factory, num_envs: int, autoreset_mode: str, render_mode: str | None) -> None:
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs!r}")
        if render_mode is not None:
            raise ValueError("render_mode is not supported by the batched env; render a single env instead")
        self.num_envs = int(num_envs)
        mode = str(autoreset_mode).lower().replace("autoresetmode.", "")
        validation.choice("autoreset_mode", mode, {"next_step", "same_step"})
        self.autoreset_mode = AutoresetMode.NEXT_STEP if mode == "next_step" else AutoresetMode.SAME_STEP
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": []}
        self.envs = [single_env_factory() for _ in range(self.num_envs)]
        if self.envs[0]._sensors.enabled or self.envs[0].fault_hint:
            raise ValueError("sensors and fault_hint are not supported by the batched env yet; use SyncVectorEnv")
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)

    def _reset_one(self, i: int, seed: int | None, options: dict | None) -> None:
        self.envs[i].reset(seed=seed, options=options)
        self._load(i)

    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed must be an int or a list of {self.num_envs} seeds, got {len(seeds)}")
        options = dict(options or {})
        reset_mask = options.pop("reset_mask", None)
        indices = range(self.num_envs) if reset_mask is None else np.flatnonzero(reset_mask)
        for i in indices:
            self._reset_one(i, seeds[i], options)
            self._needs_reset[i] = False
        return self._observations(), {}

    def _check_actions(self, actions, n_actions: int) -> np.ndarray:
        a = np.asarray(actions, dtype=float)
        if a.shape != (self.num_envs, n_actions):
            raise ValueError(f"actions must have shape ({self.num_envs}, {n_actions}), got {a.shape}")
        if not np.isfinite(a.sum()) and not np.isfinite(a).all():
            raise ValueError("actions must be finite (no NaN or inf)")
        return a

    def step(self, actions):
        rewards, terminated, truncated, infos = self._advance(actions)
        skipped = self._needs_reset.copy()
        if skipped.any():  # next-step autoreset: these sub-envs ended last step
            for i in np.flatnonzero(skipped):
                self._reset_one(i, None, None)
            rewards[skipped] = 0.0
            terminated[skipped] = False
            truncated[skipped] = False
            infos["cost"][skipped] = 0.0
            infos["_cost"] = ~skipped
        obs = self._observations()
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._needs_reset = done
        elif done.any():
            final_obs = np.empty(self.num_envs, dtype=object)  # one array per sub-env (gymnasium's layout)
            for i in np.flatnonzero(done):
                final_obs[i] = obs[i].copy()
                self._reset_one(i, None, None)
            infos["final_obs"] = final_obs
            infos["_final_obs"] = done.copy()
            obs = self._observations()
        return obs, rewards, terminated, truncated, infos

    @staticmethod
    def _with_masks(arrays: dict[str, np.ndarray], n: int) -> dict:
        infos: dict[str, Any] = {}
        for key, value in arrays.items():
            infos[key] = value
            infos["_" + key] = np.ones(n, dtype=bool)
        return infos
