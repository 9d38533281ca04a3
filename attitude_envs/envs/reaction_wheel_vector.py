"""Natively batched ReactionWheel-v0: all envs advance in one compiled SIMD call.

``gymnasium.make_vec("attitude_envs/ReactionWheel-v0", num_envs=N,
vectorization_mode="vector_entry_point", **env_kwargs)``. Sub-env ``i`` reset with seed
``s`` follows exactly the trajectory of a single ``ReactionWheel-v0`` reset with ``s + i``
(the same compiled step, :mod:`attitude_envs.plants.gyrostat_kernels`, with one env per
SIMD lane; a test checks bitwise equality). Faults and disturbances are applied per
sub-env in Python, so only batches that have them pay.
"""

from __future__ import annotations

import numpy as np

from attitude_envs.envs.air_bearing import AirBearingEnv
from attitude_envs.envs.reaction_wheel import ReactionWheelEnv
from attitude_envs.envs.vector_base import BatchedEnv
from attitude_envs.plants import gyrostat_kernels as kernels

_TWO_RAD_TO_DEG = 2.0 * (180.0 / np.pi)  # np.degrees multiplies by 180/π; times 2 is exact


class ReactionWheelVectorEnv(BatchedEnv):
    """``num_envs`` ReactionWheel-v0 envs stepped as one array (see :class:`BatchedEnv` for
    autoreset). Infos are dicts of arrays with gymnasium's ``_key`` masks: ``cost`` and
    ``time_s``, and the ground truth (:mod:`attitude_envs.info`) in ``infos["truth"]``:
    ``applied`` (N·m) and ``error_angle_deg``.

    The states live in the kernel's blocked struct-of-arrays layout
    (:func:`~attitude_envs.plants.gyrostat_kernels.blocks`); :attr:`states` gives them as
    (E, 7+N) rows."""

    single_env_class = ReactionWheelEnv

    def __init__(self, num_envs: int = 1, autoreset_mode: str = "next_step", render_mode: str | None = None, **kwargs):
        super().__init__(lambda: self.single_env_class(**kwargs), num_envs, autoreset_mode, render_mode)
        first = self.envs[0]
        self.model = first.model
        p = first.model.params
        e, n, lanes = self.num_envs, p.n_wheels, kernels.BATCH_LANES
        self._n_wheels = n
        self._max_speed = p.max_wheel_speed_rad_s
        self._max_torque = p.max_wheel_torque_nm
        self._dt = first.control_dt_s
        self._observe_wheels = first.observe_wheel_speeds
        self._n_obs = first.observation_size
        include_h, body_input = self.model.include_wheel_momentum, self.model.cost_input == "body"
        self._kernel = kernels.kernel_for(self.model, lanes, first.true_offset_torque_nm)
        self._work = np.zeros(kernels.work_size(n, lanes, include_h, body_input))
        self._constants = first.kernel_constants  # shared by all sub-envs (same keywords)
        self._substeps = first.n_substeps
        self._Y = kernels.blocks(e, 7 + n, lanes)
        self._T = kernels.blocks(e, 4, lanes)
        self._Y[:, 3, :] = self._T[:, 3, :] = 1.0  # identity attitudes in the padding lanes
        self._M = kernels.blocks(e, kernels.MAT_ROWS, lanes)
        self._has_disturbance = first.disturbance is not None
        self._ext = kernels.blocks(e, 9 * self._substeps if self._has_disturbance else 0, lanes)
        self._steps = np.zeros(e, dtype=np.int64)
        self._faulty = np.zeros(e, dtype=bool)
        self._n_faulty = 0
        self._n_actions = self.single_action_space.shape[0]

    def _reset_sub(self, i: int, seed: int | None, options: dict | None) -> None:
        self.envs[i].reset_episode(seed, options)

    def _load(self, i: int) -> None:
        sub = self.envs[i]
        b, lane = divmod(i, kernels.BATCH_LANES)
        self._Y[b, :, lane] = sub.state_row
        self._T[b, :, lane] = sub.target_attitude
        self._M[b, :, lane] = sub.kernel_matrices
        self._steps[i] = 0
        faulty = bool(sub.fault_layer.realized)
        self._n_faulty += int(faulty) - int(self._faulty[i])
        self._faulty[i] = faulty

    def _observations(self, indices=None) -> np.ndarray:
        idx = np.arange(self.num_envs) if indices is None else np.asarray(indices)
        b, lane = np.divmod(idx, kernels.BATCH_LANES)
        y = np.ascontiguousarray(self._Y[b, :, lane].T)
        x = np.empty((self.model.n_state, idx.size))
        kernels.error_state_columns(
            y,
            np.ascontiguousarray(self._T[b, :, lane].T),
            self.model.params.wheel_inertia_kg_m2,
            self.model.include_wheel_momentum,
            x,
            np.empty(idx.size),
        )
        obs = x.T
        if self._observe_wheels:
            obs = np.concatenate([obs, y[7:].T / self._max_speed], axis=1)
        return obs.astype(np.float32)

    def _advance(self, actions):
        first = self.envs[0]
        a = np.asarray(actions, dtype=np.float64)
        e, n = self.num_envs, self._n_wheels
        if a.shape != (e, self._n_actions):
            raise ValueError(f"actions must have shape ({e}, {self._n_actions}), got {a.shape}")
        # sub-envs about to be reset (next-step autoreset) take no draws: their generators
        # go on as the single env's, whose next episode starts with the reset
        live = ~self._needs_reset if self._n_needs_reset else self._all_envs
        scale = self._n_faulty == 0 and first.action_frame == "wheel"  # the kernel clips and scales
        if not scale:  # faults act on, or the body frame allocates, the commanded torques first
            a = first.commanded_torques(self._check_actions(a, self._n_actions))
            for i in np.flatnonzero(self._faulty & live):
                a[i] = self.envs[i].fault_layer.apply(a[i], self._steps[i] * self._dt)
        if self._has_disturbance:
            for i in np.flatnonzero(live):
                env = self.envs[i]
                env.disturbance.advance(env.np_random, self._dt)
                stages = env.disturbance_stages(self._steps[i] * self._dt)
                self._ext[i // kernels.BATCH_LANES, :, i % kernels.BATCH_LANES] = stages.ravel()
        obs = np.empty((e, self._n_obs), dtype=np.float32)
        time_s = np.empty(e)
        cost = np.empty(e)
        reward = np.empty(e)
        applied = np.empty((e, n))
        angle = np.empty(e)
        terminated = np.empty(e, dtype=bool)
        truncated = np.empty(e, dtype=bool)
        n_done = self._kernel(
            self._Y,
            a,
            scale,
            self._ext,
            self._M,
            self._T,
            self._constants,
            self._substeps,
            self._steps,
            time_s,
            applied,
            cost,
            reward,
            obs,
            angle,
            terminated,
            truncated,
            self._observe_wheels,
            self._work,
        )
        if n_done < 0:
            raise ValueError("actions must be finite (no NaN or inf)")
        if n_done and terminated.any():
            self._charge_termination(terminated, time_s, cost, reward)
        np.arccos(angle, out=angle)  # min(1, q_e,w) → error angle, deg: the single env's
        angle *= _TWO_RAD_TO_DEG  # np.degrees(2 arccos(.)), bit for bit
        infos = self._with_masks(
            {"cost": cost, "time_s": time_s, "truth": {"applied": applied, "error_angle_deg": angle}}
        )
        return obs, reward, terminated, truncated, infos

    def _charge_termination(self, terminated, time_s, cost, reward) -> None:
        """Add the single env's termination cost to the sub-envs that crossed a limit this
        step (finite state and cost), in place."""
        idx = np.flatnonzero(terminated)
        rows = self.states[idx]
        ok = np.isfinite(rows).all(axis=1) & np.isfinite(cost[idx])
        idx, rows = idx[ok], rows[ok]
        if idx.size == 0:
            return
        lanes = kernels.BATCH_LANES
        targets = self._T[idx // lanes, :, idx % lanes]
        first = self.envs[0]
        cost[idx] += first.batch_termination_cost(first.error_states(rows, targets), time_s[idx])
        reward[idx] = -cost[idx]

    @property
    def states(self) -> np.ndarray:
        """True physical states ``[q, ω, Ω]`` of all sub-envs (E × (7+N)), a read-only copy."""
        rows = self._Y.transpose(0, 2, 1).reshape(-1, self._Y.shape[1])[: self.num_envs]
        rows.setflags(write=False)
        return rows


class AirBearingVectorEnv(ReactionWheelVectorEnv):
    """Natively batched AirBearing-v0 (the same compiled step, with the offset torque and
    the roll/pitch stop)."""

    single_env_class = AirBearingEnv
