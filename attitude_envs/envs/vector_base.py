"""Shared machinery of the natively batched envs: seeding, resets and autoreset.

A batched env keeps one single-env instance per sub-env for resets (so initial-state,
inertia and fault draws are exactly the single env's) and advances all sub-envs in one
compiled call. Sub-env ``i`` reset with seed ``s`` follows the single env reset with
``s + i``, as gymnasium's and SB3's vector envs seed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from attitude_envs import validation


class BatchedEnv(VectorEnv):
    """Subclasses implement ``_load(i)`` (copy sub-env ``i``'s fresh state into the batch
    arrays), ``_advance(actions)`` (one batched step → new arrays of observations, rewards,
    terminated, truncated and an info dict of arrays with a ``cost`` entry, see
    :meth:`_with_masks`; sub-envs in ``_needs_reset`` are reset right after it, so it
    takes no random draws for them) and ``_observations(indices)`` (of the given sub-envs,
    all when None).

    ``autoreset_mode``: ``"next_step"`` (gymnasium's default: the step after an episode
    ends resets that sub-env, ignores its action, reward 0, and its infos are masked out)
    or ``"same_step"`` (the sub-env resets in the step that ends it;
    ``infos["final_obs"]`` holds its last observation; what SB3 expects).

    A sub-env whose step crosses a limit (``terminated``), or that starts beyond one, observes
    its state clipped to the single observation space, as the single env does
    (:meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`).

    Every array ``step`` returns is new (the env keeps no reference to it), so callers may
    keep and modify them; the ``_key`` masks of the infos are shared read-only arrays.
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
        conditions = self.envs[0].conditions
        if not conditions.is_lab:  # one set of plant constants, no delay line or actuator dynamics
            raise ValueError(
                f"conditions={conditions.name!r} ({conditions.as_dict()}): the batched env runs the lab conditions "
                "only; use gymnasium.vector.SyncVectorEnv (vectorization_mode='sync') for flight conditions"
            )
        if self.envs[0].sensor_layer.enabled or self.envs[0].fault_hint:
            raise ValueError("sensors and fault_hint are not supported by the batched env yet; use SyncVectorEnv")
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._n_needs_reset = 0
        self._never_reset = np.ones(self.num_envs, dtype=bool)  # step needs every sub-env reset once
        self._all_reset = False
        self._all_envs = np.ones(self.num_envs, dtype=bool)
        self._all_envs.setflags(write=False)

    def _reset_sub(self, i: int, seed: int | None, options: dict | None) -> None:
        """Reset sub-env ``i`` (its own draws, its own generator); subclasses may skip
        building the sub-env's observation and info, which the batch does not use."""
        self.envs[i].reset(seed=seed, options=options)

    def _reset_one(self, i: int, seed: int | None, options: dict | None) -> None:
        self._reset_sub(i, seed, options)
        self._load(i)

    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed must be an int or a list of {self.num_envs} seeds, got {len(seeds)}")
        options = validation.mapping("reset options", options)
        reset_mask = options.pop("reset_mask", None)
        indices = range(self.num_envs) if reset_mask is None else np.flatnonzero(reset_mask)
        for i in indices:
            self._reset_one(i, seeds[i], options)
            self._needs_reset[i] = False
            self._never_reset[i] = False
        self._all_reset = not self._never_reset.any()
        self._n_needs_reset = int(np.count_nonzero(self._needs_reset))
        return self._clip(self._observations()), {}

    def _clip(self, obs: np.ndarray) -> np.ndarray:
        """Rows of observations clipped to the single observation space, in place (rows inside
        it keep their bits): the single env's
        :meth:`~attitude_envs.envs.base.AttitudeEnv.clip_observation`."""
        space = self.single_observation_space
        return np.clip(obs, space.low, space.high, out=obs)

    def _check_actions(self, actions, n_actions: int) -> np.ndarray:
        """``actions`` as a float64 (num_envs, n_actions) array (no copy when it is one)."""
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != (self.num_envs, n_actions):
            raise ValueError(f"actions must have shape ({self.num_envs}, {n_actions}), got {a.shape}")
        if not np.isfinite(a.sum()) and not np.isfinite(a).all():
            raise ValueError("actions must be finite (no NaN or inf)")
        return a

    def step(self, actions):
        if not self._all_reset:
            raise ResetNeeded(
                f"Cannot call step() before calling reset(): sub-envs {np.flatnonzero(self._never_reset).tolist()} "
                f"of this batched env have never been reset; call reset() first"
            )
        obs, rewards, terminated, truncated, infos = self._advance(actions)
        if self._n_needs_reset:  # next-step autoreset: these sub-envs ended last step
            skipped = self._needs_reset
            idx = np.flatnonzero(skipped)
            for i in idx:
                self._reset_one(i, None, None)
            obs[idx] = self._observations(idx)
            rewards[idx] = 0.0
            terminated[idx] = False
            truncated[idx] = False
            infos["cost"][idx] = 0.0
            stepped = ~skipped
            stepped.setflags(write=False)
            _set_masks(infos, stepped)
        n_terminated = int(np.count_nonzero(terminated))
        if n_terminated or self._n_needs_reset:  # a limit crossed or a start: clipped as the single env's
            self._clip(obs)
        n_done = n_terminated + int(np.count_nonzero(truncated))
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if n_done:
                self._needs_reset = terminated | truncated
            elif self._n_needs_reset:
                self._needs_reset = np.zeros(self.num_envs, dtype=bool)
            self._n_needs_reset = n_done
        elif n_done:
            done = terminated | truncated
            idx = np.flatnonzero(done)
            final_obs = np.empty(self.num_envs, dtype=object)  # one array per sub-env (gymnasium's layout)
            for i in idx:
                final_obs[i] = obs[i].copy()
                self._reset_one(i, None, None)
            obs[idx] = self._clip(self._observations(idx))
            infos["final_obs"] = final_obs
            infos["_final_obs"] = done
        return obs, rewards, terminated, truncated, infos

    def _with_masks(self, arrays: dict[str, Any], n: int | None = None) -> dict:
        """Per-sub-env info arrays with gymnasium's ``_key`` masks (all sub-envs: one shared
        read-only array); a nested dict of arrays (``"truth"``) gets its own masks too."""
        infos: dict[str, Any] = {}
        for key, value in arrays.items():
            infos[key] = self._with_masks(value) if isinstance(value, dict) else value
            infos["_" + key] = self._all_envs
        return infos


def _set_masks(infos: dict[str, Any], mask: np.ndarray) -> None:
    """Set every ``_key`` mask of ``infos`` (and of its nested dicts) to ``mask``."""
    for key in [k for k in infos if not k.startswith("_")]:
        infos["_" + key] = mask
        if isinstance(infos[key], dict):
            _set_masks(infos[key], mask)
