"""Natively batched FuelSlosh-v0: all sub-envs advance in one compiled call.

``gymnasium.make_vec("attitude_envs/FuelSlosh-v0", num_envs=N,
vectorization_mode="vector_entry_point", **env_kwargs)``. Sub-env ``i`` reset with seed
``s`` follows exactly the trajectory of a single ``FuelSlosh-v0`` reset with ``s + i``
(the same compiled step; a test checks bitwise equality). Faults are applied per sub-env
in Python, so only the sub-envs that have them pay.
"""

from __future__ import annotations

import numpy as np

from attitude_envs.envs.fuel_slosh import FuelSloshEnv
from attitude_envs.envs.vector_base import BatchedEnv
from attitude_envs.info import TRUTH
from attitude_envs.plants import slosh
from attitude_envs.plants import slosh_kernels as kernels
from attitude_envs.plants.slosh_model import REDUCED_INDEX


class FuelSloshVectorEnv(BatchedEnv):
    """``num_envs`` FuelSlosh-v0 envs stepped as one array (see :class:`BatchedEnv` for
    autoreset). Infos are dicts of arrays with gymnasium's ``_key`` masks: ``cost``,
    ``time_s``, ``commanded`` ([δ rad, M_c N·m] the actions asked for, before clipping)
    and the ground truth under ``truth``: ``applied`` ([δ rad, M_c N·m] after clipping and
    faults) and ``new_inputs`` (step-mean [a_z m/s², Ω̇ rad/s²] the true plant realized). It reads the sub-envs only
    through their public members (``state``, ``fault_layer``, ``observation_index``,
    ``actuator_limits``, ``kernel_constants``, ``batch_termination``)."""

    def __init__(self, num_envs: int = 1, autoreset_mode: str = "next_step", render_mode: str | None = None, **kwargs):
        super().__init__(lambda: FuelSloshEnv(**kwargs), num_envs, autoreset_mode, render_mode)
        first = self.envs[0]
        self.model = first.model
        e = self.num_envs
        self._states = np.zeros((e, slosh.N_STATE))
        self._steps = np.zeros(e, dtype=np.int64)
        self._new_inputs = np.zeros((e, 2))
        self._costs = np.zeros(e)
        self._work = np.zeros(kernels.WORK_SIZE)
        self._faulty = np.zeros(e, dtype=bool)
        self._finite = np.ones(e, dtype=bool)

    def _load(self, i: int) -> None:
        sub = self.envs[i]
        self._states[i] = sub.state
        self._steps[i] = 0
        self._faulty[i] = bool(sub.fault_layer.realized)
        self._finite[i] = True

    def _observations(self, indices=None) -> np.ndarray:
        rows = slice(None) if indices is None else indices
        obs = self._states[rows][:, self.envs[0].observation_index].astype(np.float32)
        obs[~self._finite[rows]] = 0.0  # as the single env reports a diverged state
        return obs

    def _advance(self, actions):
        first = self.envs[0]
        a = self._check_actions(actions, 2)
        limits = first.actuator_limits
        commanded = a * limits
        applied = np.minimum(np.maximum(a, -1.0), 1.0) * limits
        # sub-envs about to be reset (next-step autoreset) skip their faults: an intermittent
        # fault draws from the sub-env's generator, which the single env would not do
        for i in np.flatnonzero(self._faulty & ~self._needs_reset):
            applied[i] = self.envs[i].fault_layer.apply(applied[i], self._steps[i] * first.control_dt_s)
        kernels.control_step_batch(
            self._states, applied, first.kernel_constants, self._new_inputs, self._costs, self._work
        )
        self._steps += 1
        new_inputs = self._new_inputs.copy()
        self._finite = (
            np.isfinite(self._costs) & np.isfinite(new_inputs).all(axis=1) & np.isfinite(self._states).all(axis=1)
        )
        terminated = ~self._finite | first.batch_termination(self._states)
        time_s = self._steps * first.control_dt_s
        charged = np.flatnonzero(terminated & self._finite)
        if charged.size:  # a limit crossed: the single env's termination cost
            x = self._states[charged][:, REDUCED_INDEX]
            self._costs[charged] += first.batch_termination_cost(x, time_s[charged])
        truncated = (time_s >= first.episode_duration_s - 1e-9 * first.control_dt_s) & ~terminated
        infos = self._with_masks(
            {
                "cost": self._costs.copy(),
                "time_s": time_s,
                "commanded": commanded,
                TRUTH: {"applied": applied, "new_inputs": new_inputs},
            }
        )
        return self._observations(), -self._costs, terminated, truncated, infos

    @property
    def states(self) -> np.ndarray:
        """True full states ``y`` of all sub-envs (E × 10, see :mod:`attitude_envs.plants.slosh`),
        read-only view."""
        view = self._states.view()
        view.setflags(write=False)
        return view
