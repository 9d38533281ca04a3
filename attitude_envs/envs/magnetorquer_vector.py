"""Natively batched Magnetorquer-v0: all sub-envs advance in one compiled call.

``gymnasium.make_vec("attitude_envs/Magnetorquer-v0", num_envs=N,
vectorization_mode="vector_entry_point", **env_kwargs)``. Sub-env ``i`` reset with seed
``s`` follows exactly the trajectory of a single ``Magnetorquer-v0`` reset with ``s + i``
(the same compiled step on the same inputs; a test checks bitwise equality). Each sub-env
keeps its own draws (orbit anomaly, true inertia, disturbance phases, IGRF table, faults);
faults and random-walk disturbances are advanced per sub-env in Python, so only the
sub-envs that have them pay. The sub-envs are read through their public interface only
(:class:`~attitude_envs.envs.magnetorquer.MagnetorquerEnv`).
"""

from __future__ import annotations

import copy

import numpy as np

from attitude_envs.envs.magnetorquer import MagnetorquerEnv
from attitude_envs.envs.vector_base import BatchedEnv
from attitude_envs.plants import magnetorquer_kernels as kernels

_DIST = slice(kernels.EN_DIST, kernels.EN_DIST + 3)  # the disturbance entry of the episode constants


class MagnetorquerVectorEnv(BatchedEnv):
    """``num_envs`` Magnetorquer-v0 envs stepped as one array (see :class:`BatchedEnv` for
    autoreset). Infos are dicts of arrays with gymnasium's ``_key`` masks: ``cost`` and
    ``time_s``; ``truth`` (the ground truth, :mod:`attitude_envs.info`, a dict of arrays with
    its own masks): ``applied`` (dipoles A·m², wheel torque N·m, after faults and the
    momentum limit) and ``error_angle_deg``."""

    def __init__(self, num_envs: int = 1, autoreset_mode: str = "next_step", render_mode: str | None = None, **kwargs):
        prototype = MagnetorquerEnv(**kwargs)
        made: list[MagnetorquerEnv] = []

        def factory() -> MagnetorquerEnv:
            # construction is deterministic (no draws before reset) and ~5x dearer than a
            # copy (the reference's polynomials): the sub-envs are copies of one fresh env
            env = copy.deepcopy(prototype) if made else prototype
            made.append(env)
            return env

        super().__init__(factory, num_envs, autoreset_mode, render_mode)
        first = self.envs[0]
        self.model = first.model
        self._shared = first.kernel_constants
        self._limits = first.model.params.limits
        self._n_obs = first.observation_size
        self._dt = first.control_dt_s
        self._duration = first.episode_duration_s
        dist = first.disturbance
        self._walks = getattr(dist, "kind", None) == "random_walk"  # drawn per step from each sub-env's RNG
        e = self.num_envs
        self._states = np.zeros((e, 8))
        self._env_vecs = np.zeros((e, kernels.ENV_SIZE))
        self._tables = np.zeros((e, 2, 3))
        self._steps = np.zeros(e, dtype=np.int64)
        self._step_out = np.zeros((e, kernels.STEP_OUT_SIZE))
        self._snaps = np.zeros((e, kernels.SNAPSHOT_SIZE))
        self._costs = np.zeros(e)
        self._work = np.zeros((e, kernels.WORK_SIZE))
        self._faulty = np.zeros(e, dtype=bool)
        self._finite = np.ones(e, dtype=bool)

    def _load(self, i: int) -> None:
        sub = self.envs[i]
        self._states[i] = sub.state_row
        self._env_vecs[i] = sub.episode_constants
        table = sub.field.table
        if table.shape != self._tables.shape[1:]:  # the IGRF table's length is known after a reset
            self._tables = np.stack(
                [e.field.table if e.field.table.shape == table.shape else 0.0 * table for e in self.envs]
            )
        self._tables[i] = table
        self._steps[i] = 0
        self._snaps[i] = sub.snapshot  # the observation and info quantities at reset
        self._work[i, kernels.WK_TAG] = np.nan  # new draws: no time context to reuse
        self._faulty[i] = bool(sub.fault_layer.realized)
        self._finite[i] = True

    def _observations(self, indices=None) -> np.ndarray:
        rows = slice(None) if indices is None else indices
        obs = self._snaps[rows, : self._n_obs].astype(np.float32)
        finite = self._finite[rows]
        if not finite.all():
            obs[~finite] = 0.0  # as the single env: zeros after a non-finite state
        return obs

    def _advance(self, actions):
        a = self._check_actions(actions, 4)
        commanded = np.minimum(np.maximum(a, -1.0), 1.0) * self._limits
        t0 = self._steps * self._dt
        # sub-envs about to be reset (next-step autoreset) take no draws: their RNG streams
        # stay those of the single env, whose next episode starts from the same state
        live = ~self._needs_reset
        if self._faulty.any():
            for i in np.flatnonzero(self._faulty & live):
                commanded[i] = self.envs[i].fault_layer.apply(commanded[i], float(t0[i]))
        if self._walks:
            for i in np.flatnonzero(live):
                env = self.envs[i]
                env.advance_disturbance()
                self._env_vecs[i, kernels.EN_DIST : kernels.EN_DIST + 3] = env.episode_constants[_DIST]
        self._steps += 1
        t1 = self._steps * self._dt
        kernels.advance_batch(
            self._states,
            commanded,
            t0,
            t1,
            self._shared,
            self._env_vecs,
            self._tables,
            self._step_out,
            self._snaps,
            self._costs,
            self._work,
        )
        self._finite = self._step_out[:, kernels.ST_FINITE] == 1.0
        terminated = ~self._finite | self.envs[0].batch_termination(self._states)
        charged = np.flatnonzero(terminated & self._finite)
        if charged.size:  # tumbling: the single env's termination cost
            x = self._snaps[charged, kernels.SN_X : kernels.SN_X + 6]
            self._costs[charged] += self.envs[0].batch_termination_cost(x, t1[charged])
        truncated = (t1 >= self._duration - 1e-9 * self._dt) & ~terminated
        truth = {"applied": self._step_out[:, :4].copy()}
        infos = self._with_masks({"cost": self._costs.copy(), "time_s": t1, "truth": truth}, self.num_envs)
        return self._observations(), -self._costs, terminated, truncated, infos

    def step(self, actions):
        obs, rewards, terminated, truncated, infos = super().step(actions)
        truth = infos["truth"]
        truth["error_angle_deg"] = self._snaps[:, kernels.SN_ANGLE].copy()
        truth["_error_angle_deg"] = infos["_truth"]  # masked out for the sub-envs next-step autoreset reset
        return obs, rewards, terminated, truncated, infos

    @property
    def states(self) -> np.ndarray:
        """True physical states ``[q (body rel. orbital frame), ω_bo, Ω]`` of all sub-envs
        (E × 8), read-only view."""
        view = self._states.view()
        view.setflags(write=False)
        return view
