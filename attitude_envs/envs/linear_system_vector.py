"""Natively batched LinearSystem-v0 (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``): every sub-env steps in one compiled call, bitwise equal to the
single env with seed ``s + i``."""

from __future__ import annotations

import numpy as np

from attitude_envs.envs.linear_system import LinearSystemEnv
from attitude_envs.envs.vector_base import BatchedEnv
from attitude_envs.info import TRUTH
from attitude_envs.plants import linear_hold, linear_kernels


class LinearSystemVectorEnv(BatchedEnv):
    """``num_envs`` LinearSystem-v0 envs as one array. Infos (dicts of arrays with
    gymnasium's ``_key`` masks): ``cost``, ``time_s``, ``commanded`` (``action_scale ·``
    the clipped actions) and the ground truth under ``truth``: ``applied`` (u after
    saturation and faults). It reads the sub-envs only through their public members
    (``state``, ``fault_layer``, ``action_scale``, ``cost``, ``decision_model``,
    ``decision_steps``, ``process_noise_std``, ``episode_steps``, ``divergence_threshold``).
    A step is a decision period of ``decision_steps`` = k plant steps (``control_dt_s``), with
    the single env's kernels (:mod:`attitude_envs.plants.linear_hold` when k > 1); ``time_s``
    and the step counts are plant steps · dt_s, as the single env's."""

    def __init__(self, num_envs: int = 1, autoreset_mode: str = "next_step", render_mode: str | None = None, **kwargs):
        super().__init__(lambda: LinearSystemEnv(**kwargs), num_envs, autoreset_mode, render_mode)
        first = self.envs[0]
        self.model = first.model
        #: the sub-envs' decision period (s), its model and its plant steps k (as the single env's)
        self.control_dt_s = first.control_dt_s
        self.decision_model = first.decision_model
        self.decision_steps = first.decision_steps
        e, n, m = self.num_envs, first.model.n, first.model.m
        self._x = np.zeros((e, n))
        self._next = np.zeros((e, n))
        self._costs = np.zeros(e)
        self._steps = np.zeros(e, dtype=np.int64)
        self._faulty = np.zeros(e, dtype=bool)
        self._m = m

    def _load(self, i: int) -> None:
        sub = self.envs[i]
        self._x[i] = sub.state
        self._steps[i] = 0
        self._faulty[i] = bool(sub.fault_layer.realized)

    def _observations(self, indices=None) -> np.ndarray:
        return (self._x if indices is None else self._x[indices]).astype(np.float32)

    def _advance(self, actions):
        first = self.envs[0]
        a = self._check_actions(actions, self._m)
        commanded = first.action_scale * np.minimum(np.maximum(a, -1.0), 1.0)
        u = commanded.copy() if self._faulty.any() else commanded
        # sub-envs about to be reset (next-step autoreset) take no draws: their generators
        # go on as the single env's, whose next episode starts with the reset
        live = ~self._needs_reset
        for i in np.flatnonzero(self._faulty & live):
            u[i] = self.envs[i].fault_layer.apply(u[i], self._steps[i] * self.model.dt_s)
        k, noise_std = first.decision_steps, first.process_noise_std
        if k == 1:
            linear_kernels.linear_step_batch(
                self._x, u, self.model.A, self.model.B, first.cost.Q, first.cost.R, self._next, self._costs
            )
            if noise_std > 0:
                for i in np.flatnonzero(live):
                    self._next[i] += noise_std * self.envs[i].np_random.normal(size=self.model.n)
        else:
            d = first.decision_model
            linear_hold.held_step_batch(self._x, u, d.A, d.B, d.Q, d.N, d.R, self._next, self._costs)
            if noise_std > 0:  # the single env's k plant steps, each with its draw (live sub-envs)
                for i in np.flatnonzero(live):
                    noise = noise_std * self.envs[i].np_random.normal(size=(k, self.model.n))
                    self._costs[i] = linear_hold.noisy_held_steps(
                        self._x[i], u[i], self.model.A, self.model.B, first.cost.Q, first.cost.R, noise, self._next[i]
                    )
        self._x, self._next = self._next, self._x
        self._steps += k  # plant steps, as the single env counts them
        bad = ~np.isfinite(self._x).all(axis=1) | (np.abs(self._x).max(axis=1) > first.divergence_threshold)
        charged = np.flatnonzero(bad)
        if charged.size:  # diverged: the single env's termination cost (finite rows only)
            charged = charged[np.isfinite(self._x[charged]).all(axis=1)]
            self._costs[charged] += first.batch_termination_cost(self._x[charged], self._steps[charged])
        truncated = (self._steps >= first.episode_steps) & ~bad
        infos = self._with_masks(
            {
                "cost": self._costs.copy(),
                "time_s": self._steps * self.model.dt_s,
                "commanded": commanded,
                TRUTH: {"applied": u},
            }
        )
        return self._observations(), -self._costs, bad, truncated, infos
