"""Natively batched ReactionWheel-v0: all envs advance in one compiled, parallel call.

``gymnasium.make_vec("attitude_envs/ReactionWheel-v0", num_envs=N,
vectorization_mode="vector_entry_point", **env_kwargs)``. Sub-env ``i`` reset with seed
``s`` follows exactly the trajectory of a single ``ReactionWheel-v0`` reset with ``s + i``
(the same compiled step; a test checks bitwise equality). Resets (initial state, inertia
and fault draws) reuse the single env's code per sub-env; steps are batched. Faults and
disturbances are applied per sub-env in Python, so only the sub-envs that have them pay.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from attitude_envs import validation
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.plants import gyrostat_kernels as kernels


class ReactionWheelVectorEnv(VectorEnv):
    """``num_envs`` ReactionWheel-v0 envs stepped as one array.

    ``autoreset_mode``: ``"next_step"`` (gymnasium's default: the step after an episode ends
    resets that sub-env and ignores its action) or ``"same_step"`` (the sub-env resets in
    the step that ends it; ``infos["final_obs"]``/``infos["final_info"]`` hold the last
    observation/info; used by the SB3 adapter). Infos are dicts of arrays with gymnasium's
    ``_key`` masks: ``cost``, ``applied`` (N·m), ``time_s``, ``error_angle_deg``.
    """

    def __init__(self, num_envs: int = 1, autoreset_mode: str = "next_step", render_mode: str | None = None, **kwargs):
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs!r}")
        if render_mode is not None:
            raise ValueError("render_mode is not supported by the batched env; render a single env instead")
        self.num_envs = int(num_envs)
        mode = validation.choice(
            "autoreset_mode", str(autoreset_mode).lower().replace("autoresetmode.", ""), {"next_step", "same_step"}
        )
        self.autoreset_mode = AutoresetMode.NEXT_STEP if mode == "next_step" else AutoresetMode.SAME_STEP
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": []}
        self.envs = [ReactionWheelEnv(**kwargs) for _ in range(self.num_envs)]
        first = self.envs[0]
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None
        self.model = first.model
        p = first.model.params
        self._n_wheels = p.n_wheels
        self._observe_wheels = first.observe_wheel_speeds
        self._max_speed = p.max_wheel_speed_rad_s
        self._max_torque = p.max_wheel_torque_nm
        self._dt = first.control_dt_s
        self._duration = first.episode_duration_s
        self._max_rate = first.max_rate_rad_s
        e, n = self.num_envs, p.n_wheels
        self._states = np.zeros((e, 7 + n))
        self._targets = np.zeros((e, 4))
        self._mats = np.zeros((e, 2, 3, 3))
        self._ext = np.zeros((e, first._substeps, 3, 3))
        self._steps = np.zeros(e, dtype=np.int64)
        self._x = np.zeros((e, first.model.n_state))
        self._qe_w = np.ones(e)
        self._applied = np.zeros((e, n))
        self._costs = np.zeros(e)
        self._work = np.zeros((e, kernels.work_size(n, first.model.n_state)))
        self._needs_reset = np.zeros(e, dtype=bool)
        self._has_disturbance = first._disturbance is not None
        self._faulty: list[int] = []

    # ------------------------------------------------------------------ helpers
    def _load(self, i: int) -> None:
        sub = self.envs[i]
        self._states[i] = sub._y
        self._targets[i] = sub._target
        self._mats[i] = sub._mats
        self._steps[i] = 0

    def _reset_one(self, i: int, seed: int | None, options: dict | None) -> None:
        self.envs[i].reset(seed=seed, options=options)
        self._load(i)

    def _observations(self) -> np.ndarray:
        kernels.error_state_batch(
            self._states,
            self._targets,
            self.model.params.wheel_inertia_kg_m2,
            self.model.include_wheel_momentum,
            self._x,
            self._qe_w,
        )
        obs = self._x
        if self._observe_wheels:
            obs = np.concatenate([obs, self._states[:, 7:] / self._max_speed], axis=1)
        return obs.astype(np.float32)

    # ------------------------------------------------------------------ gym API
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
        self._faulty = [i for i, env in enumerate(self.envs) if env._faults.realized]
        obs = self._observations()
        return obs, {}

    def step(self, actions):
        a = np.asarray(actions, dtype=float)
        if a.shape != (self.num_envs, self._n_wheels):
            raise ValueError(f"actions must have shape ({self.num_envs}, {self._n_wheels}), got {a.shape}")
        if not np.isfinite(a.sum()) and not np.isfinite(a).all():
            raise ValueError("actions must be finite (no NaN or inf)")
        commanded = np.minimum(np.maximum(a, -1.0), 1.0) * self._max_torque
        first = self.envs[0]
        if self._faulty:
            for i in self._faulty:
                commanded[i] = self.envs[i]._faults.apply(commanded[i], self._steps[i] * self._dt)
        if self._has_disturbance:
            for i, env in enumerate(self.envs):
                env._t = self._steps[i] * self._dt
                env._disturbance.advance(env.np_random, self._dt)
                env._fill_disturbance_stages()
                self._ext[i] = env._ext_stages
        kernels.control_step_batch(
            self._states,
            commanded,
            self._ext,
            self._mats,
            first.model.params.wheel_axes,
            first._scalars,
            first._flags,
            self._targets,
            first.model.cost.Q,
            first.model.cost.R,
            self._applied,
            self._costs,
            self._work,
        )
        self._steps += 1
        rewards = -self._costs
        finite = np.isfinite(self._states).all(axis=1) & np.isfinite(self._costs)
        terminated = ~finite | (np.abs(self._states[:, 4:7]).max(axis=1) > self._max_rate)
        truncated = (self._steps * self._dt >= self._duration - 1e-9 * self._dt) & ~terminated
        skipped = self._needs_reset.copy()
        if skipped.any():  # next-step autoreset: these sub-envs ended last step
            for i in np.flatnonzero(skipped):
                self._reset_one(i, None, None)
            rewards[skipped] = 0.0
            terminated[skipped] = False
            truncated[skipped] = False
        obs = self._observations()
        infos = self._infos(skipped)
        done = terminated | truncated
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._needs_reset = done
        elif done.any():
            infos["final_obs"] = np.array([obs[i] if done[i] else None for i in range(self.num_envs)], dtype=object)
            infos["_final_obs"] = done.copy()
            infos["final_info"] = {"cost": self._costs.copy(), "_cost": done.copy()}
            infos["_final_info"] = done.copy()
            for i in np.flatnonzero(done):
                self._reset_one(i, None, None)
            obs = self._observations()
        if self._faulty or done.any() or skipped.any():
            self._faulty = [i for i, env in enumerate(self.envs) if env._faults.realized]
        return obs, rewards, terminated, truncated, infos

    def _infos(self, skipped: np.ndarray) -> dict:
        ok = ~skipped
        return {
            "cost": np.where(skipped, 0.0, self._costs),
            "_cost": ok,
            "applied": self._applied.copy(),
            "_applied": ok,
            "time_s": self._steps * self._dt,
            "_time_s": np.ones(self.num_envs, dtype=bool),
            "error_angle_deg": np.degrees(2.0 * np.arccos(np.minimum(1.0, self._qe_w))),
            "_error_angle_deg": np.ones(self.num_envs, dtype=bool),
        }

    @property
    def states(self) -> np.ndarray:
        """True physical states ``[q, ω, Ω]`` of all sub-envs (E × (7+N)), read-only view."""
        view = self._states.view()
        view.setflags(write=False)
        return view
