"""Natively batched ReactionWheel-v0: all envs advance in one compiled, parallel call.

``gymnasium.make_vec("attitude_envs/ReactionWheel-v0", num_envs=N,
vectorization_mode="vector_entry_point", **env_kwargs)``. Sub-env ``i`` reset with seed
``s`` follows exactly the trajectory of a single ``ReactionWheel-v0`` reset with ``s + i``
(the same compiled step; a test checks bitwise equality). Faults and disturbances are
applied per sub-env in Python, so only the sub-envs that have them pay.
"""

from __future__ import annotations

import numpy as np

from attitude_envs.envs.air_bearing import AirBearingEnv
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.envs.vector_base import BatchedEnv
from attitude_envs.plants import gyrostat_kernels as kernels


class ReactionWheelVectorEnv(BatchedEnv):
    """``num_envs`` ReactionWheel-v0 envs stepped as one array (see :class:`BatchedEnv` for
    autoreset). Infos are dicts of arrays with gymnasium's ``_key`` masks: ``cost``,
    ``applied`` (N·m), ``time_s``, ``error_angle_deg``."""

    single_env_class = ReactionWheelEnv

    def __init__(self, num_envs: int = 1, autoreset_mode: str = "next_step", render_mode: str | None = None, **kwargs):
        super().__init__(lambda: self.single_env_class(**kwargs), num_envs, autoreset_mode, render_mode)
        first = self.envs[0]
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
        self._has_disturbance = first._disturbance is not None
        self._faulty = np.zeros(e, dtype=bool)

    def _load(self, i: int) -> None:
        sub = self.envs[i]
        self._states[i] = sub._y
        self._targets[i] = sub._target
        self._mats[i] = sub._mats
        self._steps[i] = 0
        self._faulty[i] = bool(sub._faults.realized)

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

    def _advance(self, actions):
        a = self._check_actions(actions, self._n_wheels)
        commanded = np.minimum(np.maximum(a, -1.0), 1.0) * self._max_torque
        for i in np.flatnonzero(self._faulty):
            commanded[i] = self.envs[i]._faults.apply(commanded[i], self._steps[i] * self._dt)
        if self._has_disturbance:
            for i, env in enumerate(self.envs):
                env._t = self._steps[i] * self._dt
                env._disturbance.advance(env.np_random, self._dt)
                env._fill_disturbance_stages()
                self._ext[i] = env._ext_stages
        first = self.envs[0]
        kernels.control_step_batch(
            self._states,
            commanded,
            self._ext,
            self._mats,
            self.model.params.wheel_axes,
            first._scalars,
            first._flags,
            self._targets,
            self.model.cost.Q,
            self.model.cost.R,
            self._applied,
            self._costs,
            self._work,
        )
        self._steps += 1
        finite = np.isfinite(self._states).all(axis=1) & np.isfinite(self._costs)
        terminated = ~finite | (np.abs(self._states[:, 4:7]).max(axis=1) > self._max_rate)
        terminated |= first.batch_termination(self._states)
        truncated = (self._steps * self._dt >= self._duration - 1e-9 * self._dt) & ~terminated
        infos = self._with_masks(
            {"cost": self._costs.copy(), "applied": self._applied.copy(), "time_s": self._steps * self._dt},
            self.num_envs,
        )
        return -self._costs, terminated, truncated, infos

    def step(self, actions):
        obs, rewards, terminated, truncated, infos = super().step(actions)
        infos.update(
            self._with_masks(
                {"error_angle_deg": np.degrees(2.0 * np.arccos(np.minimum(1.0, self._qe_w)))}, self.num_envs
            )
        )
        return obs, rewards, terminated, truncated, infos

    @property
    def states(self) -> np.ndarray:
        """True physical states ``[q, ω, Ω]`` of all sub-envs (E × (7+N)), read-only view."""
        view = self._states.view()
        view.setflags(write=False)
        return view


class AirBearingVectorEnv(ReactionWheelVectorEnv):
    """Natively batched AirBearing-v0 (same compiled step with the offset torque; the tilt
    stop through :meth:`AirBearingEnv.batch_termination`)."""

    single_env_class = AirBearingEnv
